"""Start the phid monitor: ingest_node and recalibration_node with config/phid.yaml.

    ros2 launch phid_ros monitor.launch.py
    ros2 launch phid_ros monitor.launch.py namespace:=/unit2 pt_ct_topic:=/unit2/ptct use_sim_time:=true
    ros2 launch phid_ros monitor.launch.py play_bag:=/path/to/phid_ros/bags/catalogue play_rate:=20

With play_bag set, the launch also runs `ros2 bag play <bag> --clock 200 --rate <play_rate>
--delay <play_delay> --wait-for-all-acked 10000` once both nodes are active (the lifecycle transition, by autostart or a
manager), and the nodes use the bag's clock (use_sim_time is forced on), so the whole pipeline runs on
recorded time. (On Jazzy `--clock` takes an optional frequency, so the bag must come first.)
Every node option a user sets at start-up is a launch argument here, passed to the nodes
typed (a 'true' string is not a bool): autostart, reliable_qos, queue_depth, store_path,
unit_id, sample_rate_hz, encoder_rate_hz, pmu_rate_hz, excitation_rate_hz,
hamiltonian_rate_hz, min_interval_s, end_of_data_s, and for a plant's recorder not_recorded,
plateau_s, held, saturation, control_systems, and for the unit's record on file (checked at every
event, verdicts on model_validation) record, record_warn_events, record_window:

    ros2 launch phid_ros monitor.launch.py play_bag:=day.mcap play_rate:=20 sample_rate_hz:=208.3332031 \
        not_recorded:=i_d,i_q,omega,delta,p_m held:=X_q=0.62 saturation:=0.1,0.4

Both nodes are managed (lifecycle) nodes. With autostart:=true (the default) each configures
and activates itself; with autostart:=false they wait unconfigured for
`ros2 lifecycle set /generator/ingest_node configure` (then activate), or a lifecycle manager.

reliable_qos defaults to `auto`: reliable when this launch plays the bag, best effort (the
sensor-data convention, config/phid.yaml) otherwise. `ros2 bag play` offers reliable, so a
reliable subscription gets every message; best effort lost the last encoder message of the
catalogue (200 samples) once in a loaded CI run, and reliable lost it too (100 samples) while the
player exited before the nodes acknowledged it, hence --wait-for-all-acked. A live driver that offers best effort
cannot match a reliable subscription, hence best effort without a bag.
"""

import os

import yaml
from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess, OpaqueFunction, RegisterEventHandler
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PythonExpression
from launch_ros.actions import LifecycleNode
from launch_ros.event_handlers import OnStateTransition
from launch_ros.parameter_descriptions import ParameterValue

# launch argument -> (type, which nodes take it); defaults come from config/phid.yaml
PASSED = {
    "autostart": (bool, ("ingest_node", "recalibration_node")),
    "reliable_qos": (bool, ("ingest_node", "recalibration_node")),
    "queue_depth": (int, ("ingest_node", "recalibration_node")),
    "sample_rate_hz": (float, ("ingest_node", "recalibration_node")),
    "encoder_rate_hz": (float, ("ingest_node", "recalibration_node")),
    "pmu_rate_hz": (float, ("ingest_node", "recalibration_node")),
    "excitation_rate_hz": (float, ("ingest_node", "recalibration_node")),
    "store_path": (str, ("recalibration_node",)),
    "unit_id": (str, ("recalibration_node",)),
    "hamiltonian_rate_hz": (float, ("recalibration_node",)),
    "min_interval_s": (float, ("recalibration_node",)),
    "end_of_data_s": (float, ("ingest_node", "recalibration_node")),
    # a plant's recorder (a trend log, a PMU export): what it never carries, and what the day's
    # datasheet holds (phid identify's --fix and --saturation)
    "not_recorded": (str, ("ingest_node", "recalibration_node")),
    "plateau_s": (float, ("ingest_node",)),
    "held": (str, ("recalibration_node",)),
    "saturation": (str, ("recalibration_node",)),
    "control_systems": (str, ("recalibration_node",)),
    # the unit's record on file (its .dyr), checked at every event: model_validation, /diagnostics
    "record": (str, ("recalibration_node",)),
    "record_warn_events": (int, ("recalibration_node",)),
    "record_window": (int, ("recalibration_node",)),
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
        ("field_controller", LaunchConfiguration("field_controller_topic")),
        ("set_point", LaunchConfiguration("set_point_topic")),
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
    nodes = [
        LifecycleNode(
            package="phid_ros",
            executable=name,
            name=name,
            namespace=ns,
            parameters=[sections[name], passed[name], common],
            remappings=remaps,
            output="screen",
        )
        for name in ("ingest_node", "recalibration_node")
    ]
    player = ExecuteProcess(
        cmd=[
            "ros2",
            "bag",
            "play",
            play_bag,
            "--clock",
            "200",
            "--rate",
            LaunchConfiguration("play_rate"),
            # discovery: the nodes' subscriptions matched before the first message goes out
            "--delay",
            LaunchConfiguration("play_delay"),
            # the player exits once it has sent the last message; a reliable message the nodes
            # had not yet acknowledged went with it (the catalogue's last encoder block, 100
            # samples, in a loaded CI run): it waits for every acknowledgement, 10 s at most
            "--wait-for-all-acked",
            "10000",
        ],
        condition=IfCondition(playing),
        output="screen",
    )
    # the bag plays once both nodes are active (autostart, or a lifecycle manager's transitions):
    # a recalibration node still compiling its numerics (10 s) missed the bag's first scenario
    # marker at 20x, and the day's first test went unlabelled
    active: set[str] = set()
    played: list[bool] = []

    def when_active(name: str) -> OpaqueFunction:
        def start(context: object) -> list:
            active.add(name)
            if played or active != {"ingest_node", "recalibration_node"}:
                return []  # the other is not active yet, or the bag already plays (a reactivation)
            played.append(True)
            return [player]

        return OpaqueFunction(function=start)

    starts = [when_active("ingest_node"), when_active("recalibration_node")]
    return LaunchDescription(
        declared
        + [
            DeclareLaunchArgument("namespace", default_value="/generator", description="namespace of both nodes"),
            DeclareLaunchArgument("use_sim_time", default_value="false", description="use the /clock topic"),
            DeclareLaunchArgument("play_bag", default_value="", description="a bag to play with --clock (optional)"),
            DeclareLaunchArgument("play_rate", default_value="1.0", description="rate of the bag playback"),
            DeclareLaunchArgument(
                "play_delay",
                default_value="2.0",
                description="seconds between both nodes being active and the playback's start",
            ),
            DeclareLaunchArgument("pt_ct_topic", default_value="pt_ct", description="PT/CT block topic"),
            DeclareLaunchArgument("encoder_topic", default_value="encoder", description="speed encoder block topic"),
            DeclareLaunchArgument("pmu_topic", default_value="pmu", description="PMU angle block topic"),
            DeclareLaunchArgument("excitation_topic", default_value="excitation", description="field voltage topic"),
            DeclareLaunchArgument(
                "field_controller_topic",
                default_value="field_controller",
                description="an excitation controller's field current / regulator / stabiliser topic (optional)",
            ),
            DeclareLaunchArgument(
                "set_point_topic",
                default_value="set_point",
                description="the voltage regulator's recorded set-point topic (optional)",
            ),
            *nodes,
        ]
        + [
            RegisterEventHandler(OnStateTransition(target_lifecycle_node=node, goal_state="active", entities=[go]))
            for node, go in zip(nodes, starts)
        ]
    )
