"""The one loop every plan runs through: each step once, what it needs first, the route named
``instead`` where a step is not ready, does not apply or cannot run, its problem said."""

from __future__ import annotations

from phid_ros.errors import StageError
from phid_ros.ident.identification import IdentificationResult, IdentifyOptions
from phid_ros.ident.results import Estimate
from phid_ros.ident.routes import Route, RouteOutput, RouteRun, run_plan


class Recorded(Route):
    """A stand-in route: says when it runs, gives its parameter ``value`` (or raises, or declines)."""

    how = "a stand-in"
    ran: list[str] = []

    def __init__(self, key: str, gives: str, value: float | None = 1.0, *, ready: bool = True, fails: bool = False):
        self.key, self.parameters, self.value, self.is_ready, self.fails = key, (gives,), value, ready, fails  # type: ignore[misc]
        self.failed_as = f"the {key} route"  # type: ignore[misc]

    def ready(self, run: RouteRun) -> bool:
        return self.is_ready

    def run(self, run: RouteRun) -> RouteOutput | None:
        Recorded.ran.append(self.key)
        if self.fails:
            raise StageError("no scenario to fit")
        if self.value is None:
            return None
        return RouteOutput({self.parameters[0]: Estimate(self.value, 0.01)})


def _run(steps: list[Route], held: dict[str, float] | None = None) -> tuple[RouteRun, IdentificationResult]:
    from phid_ros.ident.constraints import Constraints

    opt = IdentifyOptions(constraints=Constraints(held or {}, {}, {}))
    res = IdentificationResult({}, "fast", [])
    run = RouteRun(res, [], opt, lambda _: None, {s.key: s for s in steps})
    Recorded.ran = []
    run_plan(steps, run)
    return run, res


def test_a_route_runs_once_after_what_it_needs_first() -> None:
    no_load = Recorded("no_load", "T_d0_prime", 4.0)
    on_line = Recorded("on_line", "X_d", 1.1)
    on_line.first = ("no_load",)  # type: ignore[misc]
    run, res = _run([on_line, no_load])  # the plan lists the no-load tests after: they ran already
    assert Recorded.ran == ["no_load", "on_line"]
    assert res.estimates["X_d"].value == 1.1 and run.how == {"T_d0_prime": "a stand-in", "X_d": "a stand-in"}
    assert set(res.timing) == {"no_load", "on_line"} and run.given == {"no_load", "on_line"}


def test_the_route_instead_runs_where_one_is_not_ready_declines_or_cannot_run() -> None:
    for first, problem in (
        (Recorded("online", "X_d", ready=False), None),
        (Recorded("online", "X_d", None), None),
        (Recorded("online", "X_d", fails=True), "the online route did not run: no scenario to fit"),
    ):
        first.instead = "steady"  # type: ignore[misc]
        run, res = _run([first, Recorded("steady", "X_d", 1.2)])
        assert res.estimates["X_d"].value == 1.2 and "online" not in run.given, first
        assert res.problems == ([problem] if problem else []), first


def test_a_held_parameter_is_not_overwritten_by_a_route() -> None:
    _, res = _run([Recorded("swing", "H", 9.0)], held={"H": 3.5})
    assert "H" not in res.estimates  # the pipeline reports it as held after the plan
