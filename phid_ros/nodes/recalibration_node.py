"""recalibration_node: event windows -> event store -> three-stage recalibration -> parameters.

Subscribes (relative, remappable): event_windows (from ingest_node), the four sensor topics
(for the Hamiltonian and stream health) and /phid/scenarios (markers, when a recording has
them). Publishes: parameters and control_parameters (the exciter, governor and stabiliser
fitted beside them; transient local), hamiltonian, /diagnostics, with tracking_enabled
tracked_parameters, and with ``record`` (the unit's .dyr) model_validation, the record's verdict
on each event. Services (std_srvs/Trigger): ~/recalibrate, ~/reset.
A managed (lifecycle) node: see :class:`phid_ros.nodes.common.MonitorNode`.
"""

from __future__ import annotations

from typing import Any

from std_srvs.srv import Trigger

from phid_ros.controls.models import KINDS_IN_ORDER as CONTROL_KINDS
from phid_ros.ident.pipeline import prepare as prepare_identification
from phid_ros.io.recording import scenario_from_message
from phid_ros.io.topics import OUTPUT_TOPICS, SCENARIO_TOPIC
from phid_ros.nodes import common
from phid_ros.stream import messages as m
from phid_ros.stream.emit import emit
from phid_ros.stream.params import RECALIBRATION, pipeline_settings
from phid_ros.stream.pipeline import MonitorPipeline, Outputs
from phid_ros.stream.recalibration import RecalibrationOutcome

# The Hamiltonian is held until the recalibration that covers it is known, then published at
# once: the first set releases about 5.5 min of samples (1650 at 5 Hz) in one burst, which a
# 100-deep reliable queue dropped in part (2685 of 3301 arrived at 20x playback).
HAMILTONIAN_DEPTH = 5000
VERDICTS_KEPT = 10  # the record's verdicts a late subscriber still gets


class RecalibrationNode(common.MonitorNode):
    last_recalibration: RecalibrationOutcome | None = None  # for /diagnostics: its level and status

    def __init__(self) -> None:
        prepare_identification()  # before any callback can wait on a first compile (seconds, once per machine)
        super().__init__("recalibration_node", RECALIBRATION)

    def build(self) -> None:
        settings = pipeline_settings(
            self.values,
            detect=False,
            store_path=self.values["store_path"],
            unit=self.values["unit_id"] or self.get_namespace(),
        )
        self.pipeline = MonitorPipeline(settings)
        if self.values["record"]:  # the unit's record on file, checked at every event
            from phid_ros.api import record_check
            from phid_ros.stream.record_check import RecordCheckSettings

            chosen = RecordCheckSettings(
                window=self.values["record_window"], warn_events=self.values["record_warn_events"]
            )
            self.pipeline.record_check = record_check(self.values["record"], settings=chosen)
        # the markers' subscription first: an executor takes ready messages in the order the
        # subscriptions were made, and a window names its event from the markers in hand. With the
        # windows' first, a window queued behind a long callback (an event played into the record,
        # a second or so) was taken before its own marker, queued beside it: on a real Jazzy launch
        # at 20x the dampingless S02 went unnamed and was played as damped (a verdict 1 % off replay's)
        self.subscription(
            self.types["phid_msgs/msg/ScenarioMarker"], SCENARIO_TOPIC, self._on_marker, common.reliable_qos()
        )
        windows, window_type = OUTPUT_TOPICS["windows"]  # the ingest node's output is our input
        self.subscription(self.types[window_type], windows, self._on_window, common.reliable_qos())
        self.publishers_by_key = {
            "parameters": self.publisher("parameters", common.latched_qos()),
            # one message per control system (exciter, governor, stabiliser) at each recalibration
            "controls": self.publisher("controls", common.latched_qos(len(CONTROL_KINDS))),
            "tracked_parameters": self.publisher("tracked_parameters", common.latched_qos()),
            "hamiltonian": self.publisher("hamiltonian", common.reliable_qos(HAMILTONIAN_DEPTH)),
            # one a checked event; a late subscriber (a planner's dashboard) gets the last few
            "model_validation": self.publisher("model_validation", common.latched_qos(VERDICTS_KEPT)),
        }
        self.diag_pub = self.publisher("diagnostics", common.reliable_qos(10))
        self.service(Trigger, "~/recalibrate", self._recalibrate)
        self.service(Trigger, "~/reset", self._reset)
        common.subscribe_sensors(self)

    def timer_periods(self) -> list[tuple[float, Any]]:
        return [
            (1.0 / self.values["hamiltonian_rate_hz"], self.process),
            (self.values["diagnostics_period_s"], self.publish_diagnostics),
        ]

    # -- callbacks ------------------------------------------------------------------------
    def _on_window(self, msg: Any) -> None:
        self._publish(self.pipeline.add_window(m.window_from_message(msg)))

    def _on_marker(self, msg: Any) -> None:
        self.pipeline.add_marker(scenario_from_message(msg))

    def _recalibrate(self, request: Any, response: Any) -> Any:
        response.message = self.pipeline.recalibrate()
        response.success = response.message == "started"
        return response

    def _reset(self, request: Any, response: Any) -> Any:
        self.pipeline.reset()
        response.success, response.message = True, "buffers and event store cleared; parameters kept"
        return response

    # -- periodic work ---------------------------------------------------------------------
    def process(self) -> None:
        # the input ended (a bag finished, a feed stopped): do now what replay does at its end,
        # the owed recalibration, so the last set is published without waiting for more data
        self._publish(self.pipeline.process(final=self.input.ended(self.values["end_of_data_s"])))

    def _publish(self, out: Outputs) -> None:
        for r in out.recalibrations:
            self.last_recalibration = r
        done = emit(self.types, out, self.publishers_by_key, common.float_seq, list)
        for p in done:
            self.publishers_by_key[p.key].publish(p.message)
        for note in done.notes:
            self.get_logger().warning(note)

    def publish_diagnostics(self) -> None:
        now = int(self.get_clock().now().nanoseconds)
        self.diag_pub.publish(
            m.diagnostics_message(
                self.types,
                now,
                self.pipeline.health,
                self.last_recalibration,
                stream_now_ns=self.pipeline.aligner.stream_now_ns,
                stale_ns=self.pipeline.aligner.stale_ns,
                level=common.byte_level,
                unit=self.pipeline.settings.unit,
                record=self.pipeline.record_check,
            )
        )


def main(args: list[str] | None = None) -> None:
    common.spin_until_shutdown(RecalibrationNode, args)


if __name__ == "__main__":
    main()
