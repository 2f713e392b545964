"""Launch the winch monitor with the package's parameter file (sites with a full ROS 2 install).

    ros2 launch cable_winch_monitor winch_monitor.launch.py plant_file:=/path/plant.yaml use_sim_time:=true
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def generate_launch_description() -> LaunchDescription:
    params = os.path.join(get_package_share_directory("cable_winch_monitor"), "config", "winch_monitor.yaml")
    plant_file = LaunchConfiguration("plant_file")
    use_sim_time = LaunchConfiguration("use_sim_time")
    return LaunchDescription([
        DeclareLaunchArgument("plant_file", default_value="",
                              description="plant YAML file; empty = the bundled seed-002 plant"),
        DeclareLaunchArgument("use_sim_time", default_value="false",
                              description="follow /clock (bag replay)"),
        Node(
            package="cable_winch_monitor",
            executable="winch_monitor",
            name="winch_monitor",
            output="screen",
            parameters=[params, {"plant_file": ParameterValue(plant_file, value_type=str),
                                 "use_sim_time": ParameterValue(use_sim_time, value_type=bool)}],
        ),
    ])
