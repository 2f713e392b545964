"""Simulated plant recordings: scenario -> true plant -> noisy sensors -> rosbag2 bag + ground truth."""
