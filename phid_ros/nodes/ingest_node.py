"""ingest_node: sensor topics -> aligned ring buffer -> disturbance events and event windows.

Subscribes (relative, remappable): pt_ct, encoder, pmu, excitation, and a recorder's field_controller
and set_point when there are (its field current and the regulator's set-point go with each window).
Publishes: events (DisturbanceEvent), event_windows (EventWindow), ~/diagnostics is left to
the recalibration node, which also watches the streams. A managed (lifecycle) node: see
:class:`phid_ros.nodes.common.MonitorNode`.
"""

from __future__ import annotations

from typing import Any

from phid_ros.nodes import common
from phid_ros.stream.detector import lost_measurement_text
from phid_ros.stream.emit import emit
from phid_ros.stream.params import INGEST, pipeline_settings
from phid_ros.stream.pipeline import MonitorPipeline


class IngestNode(common.MonitorNode):
    def __init__(self) -> None:
        super().__init__("ingest_node", INGEST)

    def build(self) -> None:
        settings = pipeline_settings(self.values, detect=True)
        settings.auto_recalibrate = False  # recalibration is the other node's job, and so is keeping the windows
        settings.keep_windows = False
        self.pipeline = MonitorPipeline(settings)
        self.publishers_by_key = {key: self.publisher(key, common.reliable_qos()) for key in ("events", "windows")}
        common.subscribe_sensors(self)

    def timer_periods(self) -> list[tuple[float, Any]]:
        return [(self.values["process_period_s"], self.process)]

    def process(self) -> None:
        # the input ended: the windows still open are cut with what came (as phid replay does at
        # a recording's end), so an event in its last seconds is published, not held forever
        lost_before = len(self.pipeline.detector.lost_measurements)
        out = self.pipeline.process(final=self.input.ended(self.values["end_of_data_s"]))
        for at, back in self.pipeline.detector.lost_measurements[lost_before:]:
            self.get_logger().warning(lost_measurement_text(at, back, ended=False))
        done = emit(self.types, out, self.publishers_by_key, common.float_seq, list)
        for p in done:
            self.publishers_by_key[p.key].publish(p.message)
        for note in done.notes:
            self.get_logger().warning(note)


def main(args: list[str] | None = None) -> None:
    common.spin_until_shutdown(IngestNode, args)


if __name__ == "__main__":
    main()
