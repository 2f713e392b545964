"""ROS 2 adapters: messages in, MonitorPipeline calls, messages out (no mechanics here)."""
