"""Mechanics of the four-cable sinking platform: pure numpy/scipy, no ROS."""
