"""Start the phid monitor: ingest_node and recalibration_node with config/phid.yaml.

    ros2 launch phid_ros monitor.launch.py
    ros2 launch phid_ros monitor.launch.py namespace:=/unit2 pt_ct_topic:=/unit2/ptct use_sim_time:=true
    ros2 launch phid_ros monitor.launch.py play_bag:=/path/to/phid_ros/bags/catalogue

With play_bag set, the launch also runs `ros2 bag play --clock <bag>` and the nodes use
the bag's clock (use_sim_time is forced on), so the whole pipeline runs on recorded time.
"""

import os

import yaml
from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PythonExpression
from launch_ros.actions import Node


def node_parameters(node: str) -> dict:
    """This node's section of config/phid.yaml, as a dict: parameter-file keys are fully
    qualified node names, and passing the values directly keeps any namespace working."""
    path = os.path.join(get_package_share_directory("phid_ros"), "config", "phid.yaml")
    with open(path, encoding="utf-8") as fh:
        return yaml.safe_load(fh)[node]["ros__parameters"]


def generate_launch_description() -> LaunchDescription:
    ns = LaunchConfiguration("namespace")
    play_bag = LaunchConfiguration("play_bag")
    playing = PythonExpression(["'", play_bag, "' != ''"])
    sim_time = PythonExpression(["'", LaunchConfiguration("use_sim_time"), "' == 'true' or ", playing])
    remaps = [
        ("pt_ct", LaunchConfiguration("pt_ct_topic")),
        ("encoder", LaunchConfiguration("encoder_topic")),
        ("pmu", LaunchConfiguration("pmu_topic")),
        ("excitation", LaunchConfiguration("excitation_topic")),
    ]
    common = {"use_sim_time": sim_time}
    return LaunchDescription(
        [
            DeclareLaunchArgument("namespace", default_value="/generator", description="namespace of both nodes"),
            DeclareLaunchArgument("use_sim_time", default_value="false", description="use the /clock topic"),
            DeclareLaunchArgument("play_bag", default_value="", description="a bag to play with --clock (optional)"),
            DeclareLaunchArgument("play_rate", default_value="1.0", description="rate of the bag playback"),
            DeclareLaunchArgument("pt_ct_topic", default_value="pt_ct", description="PT/CT block topic"),
            DeclareLaunchArgument("encoder_topic", default_value="encoder", description="speed encoder block topic"),
            DeclareLaunchArgument("pmu_topic", default_value="pmu", description="PMU angle block topic"),
            DeclareLaunchArgument("excitation_topic", default_value="excitation", description="field voltage topic"),
            Node(
                package="phid_ros",
                executable="ingest_node",
                name="ingest_node",
                namespace=ns,
                parameters=[node_parameters("ingest_node"), common],
                remappings=remaps,
                output="screen",
            ),
            Node(
                package="phid_ros",
                executable="recalibration_node",
                name="recalibration_node",
                namespace=ns,
                parameters=[node_parameters("recalibration_node"), common],
                remappings=remaps,
                output="screen",
            ),
            ExecuteProcess(
                cmd=["ros2", "bag", "play", "--clock", play_bag], condition=IfCondition(playing), output="screen"
            ),
        ]
    )
