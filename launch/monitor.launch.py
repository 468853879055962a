"""Start the phid monitor: ingest_node and recalibration_node with config/phid.yaml.

    ros2 launch phid_ros monitor.launch.py
    ros2 launch phid_ros monitor.launch.py namespace:=/unit2 pt_ct_topic:=/unit2/ptct use_sim_time:=true
    ros2 launch phid_ros monitor.launch.py play_bag:=/path/to/phid_ros/bags/catalogue play_rate:=20

With play_bag set, the launch also runs `ros2 bag play <bag> --clock 200 --rate <play_rate>
--delay <play_delay>`
and the nodes use the bag's clock (use_sim_time is forced on), so the whole pipeline runs on
recorded time. (On Jazzy `--clock` takes an optional frequency, so the bag must come first.)
Every node option a user sets at start-up is a launch argument here, passed to the nodes
typed (a 'true' string is not a bool): autostart, reliable_qos, queue_depth, store_path,
unit_id, sample_rate_hz, encoder_rate_hz, pmu_rate_hz, excitation_rate_hz,
hamiltonian_rate_hz, min_interval_s, end_of_data_s.

Both nodes are managed (lifecycle) nodes. With autostart:=true (the default) each configures
and activates itself; with autostart:=false they wait unconfigured for
`ros2 lifecycle set /generator/ingest_node configure` (then activate), or a lifecycle manager.

reliable_qos defaults to `auto`: reliable when this launch plays the bag, best effort (the
sensor-data convention, config/phid.yaml) otherwise. `ros2 bag play` offers reliable, so a
reliable subscription gets every message; best effort lost the last encoder message of the
catalogue (200 samples) once in a loaded CI run. A live driver that offers best effort
cannot match a reliable subscription, hence best effort without a bag.
"""

import os

import yaml
from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PythonExpression
from launch_ros.actions import LifecycleNode
from launch_ros.parameter_descriptions import ParameterValue

# launch argument -> (type, which nodes take it); defaults come from config/phid.yaml
PASSED = {
    "autostart": (bool, ("ingest_node", "recalibration_node")),
    "reliable_qos": (bool, ("ingest_node", "recalibration_node")),
    "queue_depth": (int, ("ingest_node", "recalibration_node")),
    "sample_rate_hz": (float, ("ingest_node",)),
    "encoder_rate_hz": (float, ("ingest_node", "recalibration_node")),
    "pmu_rate_hz": (float, ("ingest_node", "recalibration_node")),
    "excitation_rate_hz": (float, ("ingest_node", "recalibration_node")),
    "store_path": (str, ("recalibration_node",)),
    "unit_id": (str, ("recalibration_node",)),
    "hamiltonian_rate_hz": (float, ("recalibration_node",)),
    "min_interval_s": (float, ("recalibration_node",)),
    "end_of_data_s": (float, ("ingest_node", "recalibration_node")),
}


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
    sections = {n: node_parameters(n) for n in ("ingest_node", "recalibration_node")}
    passed = {n: {} for n in sections}
    declared = []
    for arg, (kind, nodes) in PASSED.items():
        default = sections[nodes[0]][arg]
        text = str(default).lower() if kind is bool else str(default)
        value = LaunchConfiguration(arg)
        if arg == "reliable_qos":
            text = "auto"
            # any other word fails the launch with a KeyError naming it, not a silent default
            value = PythonExpression(["{'true': True, 'false': False, 'auto': ", playing, "}['", value, "']"])
        declared.append(
            DeclareLaunchArgument(
                arg,
                default_value=text,
                description=f"node parameter {arg}"
                + (": true, false or auto (reliable when play_bag is set)" if arg == "reliable_qos" else ""),
            )
        )
        for n in nodes:
            passed[n][arg] = ParameterValue(value, value_type=kind)
    return LaunchDescription(
        declared
        + [
            DeclareLaunchArgument("namespace", default_value="/generator", description="namespace of both nodes"),
            DeclareLaunchArgument("use_sim_time", default_value="false", description="use the /clock topic"),
            DeclareLaunchArgument("play_bag", default_value="", description="a bag to play with --clock (optional)"),
            DeclareLaunchArgument("play_rate", default_value="1.0", description="rate of the bag playback"),
            DeclareLaunchArgument(
                "play_delay", default_value="8.0", description="seconds before playback starts (the nodes start first)"
            ),
            DeclareLaunchArgument("pt_ct_topic", default_value="pt_ct", description="PT/CT block topic"),
            DeclareLaunchArgument("encoder_topic", default_value="encoder", description="speed encoder block topic"),
            DeclareLaunchArgument("pmu_topic", default_value="pmu", description="PMU angle block topic"),
            DeclareLaunchArgument("excitation_topic", default_value="excitation", description="field voltage topic"),
            LifecycleNode(
                package="phid_ros",
                executable="ingest_node",
                name="ingest_node",
                namespace=ns,
                parameters=[sections["ingest_node"], passed["ingest_node"], common],
                remappings=remaps,
                output="screen",
            ),
            LifecycleNode(
                package="phid_ros",
                executable="recalibration_node",
                name="recalibration_node",
                namespace=ns,
                parameters=[sections["recalibration_node"], passed["recalibration_node"], common],
                remappings=remaps,
                output="screen",
            ),
            ExecuteProcess(
                cmd=[
                    "ros2",
                    "bag",
                    "play",
                    play_bag,
                    "--clock",
                    "200",
                    "--rate",
                    LaunchConfiguration("play_rate"),
                    # the nodes need a few seconds to start (numpy, scipy): data sent before they
                    # subscribe is lost, and at 20x three seconds are a minute of recording
                    "--delay",
                    LaunchConfiguration("play_delay"),
                ],
                condition=IfCondition(playing),
                output="screen",
            ),
        ]
    )
