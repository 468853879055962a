"""ingest_node: sensor topics -> aligned ring buffer -> disturbance events and event windows.

Subscribes (relative, remappable): pt_ct, encoder, pmu, excitation.
Publishes: events (DisturbanceEvent), event_windows (EventWindow), ~/diagnostics is left to
the recalibration node, which also watches the streams.
"""

from __future__ import annotations

from typing import Any

from rclpy.node import Node

from phid_ros.io.topics import STREAMS_BY_NAME
from phid_ros.nodes.common import (
    SENSOR_TOPICS,
    declare,
    float_seq,
    msg_types,
    now_ns,
    on_set,
    output_publisher,
    reliable_qos,
    sensor_qos,
    spin_until_shutdown,
    steady_timer,
)
from phid_ros.stream import messages as m
from phid_ros.stream.params import INGEST, apply, pipeline_settings
from phid_ros.stream.pipeline import MonitorPipeline


class IngestNode(Node):
    def __init__(self) -> None:
        super().__init__("ingest_node")
        self.values = declare(self, INGEST)
        settings = pipeline_settings(self.values, detect=True)
        settings.auto_recalibrate = False  # recalibration is the other node's job, and so is keeping the windows
        settings.keep_windows = False
        self.pipeline = MonitorPipeline(settings)
        self.types = msg_types()
        qos = sensor_qos(self.values["reliable_qos"], self.values["queue_depth"])
        for name in SENSOR_TOPICS:
            cls = self.types[STREAMS_BY_NAME[name].msgtype]
            self.create_subscription(cls, name, self._sensor_callback(name), qos)
        self.events_pub = output_publisher(self, "events", reliable_qos())
        self.windows_pub = output_publisher(self, "windows", reliable_qos())
        self.add_on_set_parameters_callback(on_set(INGEST, self._apply))
        steady_timer(self, self.values["process_period_s"], self.process)
        self.get_logger().info(
            f"ready: {', '.join(SENSOR_TOPICS)} ({'reliable' if self.values['reliable_qos'] else 'best effort'}, "
            f"depth {self.values['queue_depth']})"
        )

    def _sensor_callback(self, stream: str) -> Any:
        channels = STREAMS_BY_NAME[stream].channels

        def callback(msg: Any) -> None:
            t0 = m.stamp_ns(msg.header.stamp)  # a zero stamp is counted and dropped by the pipeline
            period = m.seconds_to_ns(msg.sample_period)
            self.pipeline.ingest_message(stream, t0, period, m.block_arrays(msg, channels), receive_ns=now_ns(self))

        return callback

    def _apply(self, name: str, value: Any) -> None:
        self.pipeline.configure(apply(self.pipeline.settings, name, value))

    def process(self) -> None:
        out = self.pipeline.process()
        for e in out.events:
            self.events_pub.publish(m.event_message(self.types, e))
        for w in out.windows:
            if w.usable:
                self.windows_pub.publish(m.window_message(self.types, w, float_seq))
            else:
                self.get_logger().warning(f"event {w.event.event_id} ({w.event.kind}) not usable: {w.reason}")


def main(args: list[str] | None = None) -> None:
    spin_until_shutdown(IngestNode, args)


if __name__ == "__main__":
    main()
