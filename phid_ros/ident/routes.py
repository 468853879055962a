"""The ways to a parameter as steps of one plan, and the one loop that runs a plan.

A :class:`Route` declares what it needs (the recorded channels, the held values, no-load or
on-line tests, the routes that must have run before it) and what it produces, and its
:meth:`Route.run` returns a :class:`RouteOutput`: estimates, typed figures, problems. The paper's
three stages on the full channel set are routes too (``ident/pipeline.py``); the routes a
recorder's channels allow are ``ident/determinable.py``'s. :func:`run_plan` runs either plan the
same way: each step once, what it needs first, each timed under its key, a step that cannot run
saying why and handing over to the route it names as ``instead``.
"""

from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from phid_ros.errors import StageError
from phid_ros.ident import terminal
from phid_ros.ident.identification import IdentificationResult, IdentifyOptions, Say
from phid_ros.ident.results import Estimate
from phid_ros.ident.route_figures import RouteFigures
from phid_ros.ident.scenario import ScenarioData


@dataclass
class RouteOutput:
    estimates: dict[str, Estimate] = field(default_factory=dict)  # of the route's parameters: given under its how
    figures: dict[str, RouteFigures] = field(default_factory=dict)  # kept under these keys (the JSON's stages)
    problems: list[str] = field(default_factory=list)
    # what it says of a parameter it does not produce (X_q from the steady states of V_t, P, Q, E_fd)
    said: dict[str, Estimate] = field(default_factory=dict)
    stage_result: Any = None  # kept as the result's ``result_as`` (stage 1's or stage 2's own result)


class Route(ABC):
    """One way to parameters: what it needs, what it produces, how it is said."""

    key: ClassVar[str]
    parameters: ClassVar[tuple[str, ...]]  # what it produces
    channels: ClassVar[tuple[str, ...]] = ()  # recorded in the scenarios it uses
    how: ClassVar[str]  # how a parameter it gives was determined (``determined_by``)
    held: ClassVar[tuple[str, ...]] = ()  # parameters the user must hold (--fix)
    no_load: ClassVar[bool] = False  # uses no-load tests (no stator current)
    loaded: ClassVar[bool] = False  # uses tests under load
    first: ClassVar[tuple[str, ...]] = ()  # routes run before it, once (T'_d0 from the no-load tests)
    instead: ClassVar[str | None] = None  # the route for its parameters when it cannot run
    says: ClassVar[str] = ""  # the progress line's subject ("H, D")
    failed_as: ClassVar[str] = ""  # the problem's subject when it raises ("stage 1 (H, D)")
    result_as: ClassVar[str | None] = None  # the result's attribute for ``stage_result``

    def scenarios(self, scs: Sequence[ScenarioData]) -> list[ScenarioData]:
        out = [s for s in scs if s.has(*self.channels)]
        if "theta_t" in self.channels:  # an angle recorded as 0 throughout is the reference, not a measurement
            out = [s for s in out if float(np.ptp(s["theta_t"])) > 0]
        if self.no_load:
            out = [s for s in out if terminal.at_no_load(s)]
        if self.loaded:
            out = [s for s in out if not terminal.at_no_load(s)]
        return out

    def ready(self, run: RouteRun) -> bool:
        """Whether what it needs beyond its channels is there (X_d known for the d axis)."""
        return True

    @abstractmethod
    def run(self, run: RouteRun) -> RouteOutput | None:
        """Its output; None where it does not apply after all (then ``instead`` runs). Raises
        StageError when it cannot run."""


@dataclass
class RouteRun:
    """One run of a plan: the result each step writes into, how each parameter was determined,
    and the steps done."""

    res: IdentificationResult
    ident: list[ScenarioData]
    opt: IdentifyOptions
    say: Say
    routes: Mapping[str, Route]  # by key: a step's ``first`` and ``instead``
    how: dict[str, str] = field(default_factory=dict)
    done: set[str] = field(default_factory=set)  # the steps that ran (or were found not ready), by key
    given: set[str] = field(default_factory=set)  # the steps whose output was taken
    cache: dict[str, Any] = field(default_factory=dict)  # what a step's ready() computed for its run()

    @property
    def held(self) -> Mapping[str, float]:
        return self.opt.constraints.fixed

    def known(self, *names: str) -> dict[str, float]:
        """The values of ``names`` as held or as the steps so far gave them (finite ones)."""
        out = {n: e.value for n, e in self.res.estimates.items() if n in names and math.isfinite(e.value)}
        out.update({n: v for n, v in self.held.items() if n in names})
        return out

    def accept(self, route: Route, out: RouteOutput) -> None:
        res = self.res
        res.problems.extend(out.problems)
        res.route_details.update(out.figures)
        if out.stage_result is not None and route.result_as:
            setattr(res, route.result_as, out.stage_result)
        for n, e in out.estimates.items():
            if n in route.parameters and n not in self.held:
                res.estimates[n] = e
                self.how[n] = route.how
        res.estimates.update(out.said)

    def once(self, route: Route) -> None:
        """``route`` unless it ran: where it is not ready, or does not apply, its ``instead``;
        else what it needs first, then itself."""
        if route.key in self.done:
            return
        self.done.add(route.key)
        if not route.ready(self):
            self._instead(route)
            return
        for key in route.first:
            self.once(self.routes[key])
        if route.says:
            self.say(f"{route.says}: {route.how}")
        t0 = time.perf_counter()
        try:
            out = route.run(self)
        except StageError as exc:
            self.res.problems.append(f"{route.failed_as} did not run: {exc}")
            out = None
        self.res.timing[route.key] = round(time.perf_counter() - t0, 6)
        if out is None:
            self._instead(route)
            return
        self.given.add(route.key)
        self.accept(route, out)

    def _instead(self, route: Route) -> None:
        if route.instead is not None:
            self.once(self.routes[route.instead])


def run_plan(steps: Sequence[Route], run: RouteRun) -> None:
    """Each step of the plan once, in order (what a step needs runs before it)."""
    for step in steps:
        run.once(step)
