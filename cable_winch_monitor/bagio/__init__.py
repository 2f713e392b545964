"""Bags without a ROS runtime: the message type store, robust MCAP reading, rosbag2 writing."""
