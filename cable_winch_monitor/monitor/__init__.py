"""What the monitor does with every sample, with no ROS in it: merge inputs, solve, clearance, alarms."""
