"""ingest_node: sensor topics -> aligned ring buffer -> disturbance events and event windows.

Subscribes (relative, remappable): pt_ct, encoder, pmu, excitation.
Publishes: events (DisturbanceEvent), event_windows (EventWindow), ~/diagnostics is left to
the recalibration node, which also watches the streams.
"""

from __future__ import annotations

from typing import Any

from rclpy.node import Node

from phid_ros.nodes import common
from phid_ros.stream.emit import emit
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
        self.publishers_by_key = {
            key: common.output_publisher(self, key, common.reliable_qos()) for key in ("events", "windows")
        }
        self.add_on_set_parameters_callback(common.on_set(INGEST, self._apply))
        common.steady_timer(self, self.values["process_period_s"], self.process)
        self.input = common.InputWatch()
        common.subscribe_sensors(self, self.input.on_data)

    def _apply(self, name: str, value: Any) -> None:
        self.pipeline.configure(apply(self.pipeline.settings, name, value))

    def process(self) -> None:
        # the input ended: the windows still open are cut with what came (as phid replay does at
        # a recording's end), so an event in its last seconds is published, not held forever
        lost_before = len(self.pipeline.detector.lost_measurements)
        out = self.pipeline.process(final=self.input.ended(self.values["end_of_data_s"]))
        for at, _ in self.pipeline.detector.lost_measurements[lost_before:]:
            self.get_logger().warning(f"V_t measurement lost at no load at stamp {at} ns: no event taken from it")
        done = emit(self.types, out, self.publishers_by_key, common.float_seq, list)
        for p in done:
            self.publishers_by_key[p.key].publish(p.message)
        for note in done.notes:
            self.get_logger().warning(note)


def main(args: list[str] | None = None) -> None:
    common.spin_until_shutdown(IngestNode, args)


if __name__ == "__main__":
    main()
