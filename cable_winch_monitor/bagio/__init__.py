"""Bag files without a ROS runtime: the message type store, CDR, robust MCAP reading and salvage, rosbag2
writing. Nothing of the monitor: its messages are `messages/`."""
