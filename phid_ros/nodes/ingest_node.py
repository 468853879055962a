"""ingest_node: sensor topics -> aligned ring buffer -> disturbance events and event windows.

Subscribes (relative, remappable): pt_ct, encoder, pmu, excitation.
Publishes: events (DisturbanceEvent), event_windows (EventWindow), ~/diagnostics is left to
the recalibration node, which also watches the streams.
"""

from __future__ import annotations

from typing import Any

from rclpy.node import Node

from phid_ros.nodes import common
from phid_ros.stream import messages as m
from phid_ros.stream.params import INGEST, apply, pipeline_settings
from phid_ros.stream.pipeline import MonitorPipeline


class IngestNode(Node):
    def __init__(self) -> None:
        super().__init__("ingest_node")
        self.values = common.declare(self, INGEST)
        settings = pipeline_settings(self.values, detect=True)
        settings.auto_recalibrate = False  # recalibration is the other node's job, and so is keeping the windows
        settings.keep_windows = False
        self.pipeline = MonitorPipeline(settings)
        self.types = common.msg_types()
        self.events_pub = common.output_publisher(self, "events", common.reliable_qos())
        self.windows_pub = common.output_publisher(self, "windows", common.reliable_qos())
        self.add_on_set_parameters_callback(common.on_set(INGEST, self._apply))
        common.steady_timer(self, self.values["process_period_s"], self.process)
        self.input = common.InputWatch()
        common.subscribe_sensors(self, self.input.on_data)

    def _apply(self, name: str, value: Any) -> None:
        self.pipeline.configure(apply(self.pipeline.settings, name, value))

    def process(self) -> None:
        # the input ended: the windows still open are cut with what came (as phid replay does at
        # a recording's end), so an event in its last seconds is published, not held forever
        out = self.pipeline.process(final=self.input.ended(self.values["end_of_data_s"]))
        for e in out.events:
            self.events_pub.publish(m.event_message(self.types, e))
        for w in out.windows:
            if w.usable:
                self.windows_pub.publish(m.window_message(self.types, w, common.float_seq))
            else:
                self.get_logger().warning(f"event {w.event.event_id} ({w.event.kind}) not usable: {w.reason}")


def main(args: list[str] | None = None) -> None:
    common.spin_until_shutdown(IngestNode, args)


if __name__ == "__main__":
    main()
