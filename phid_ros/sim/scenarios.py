"""Scenario definitions and the paper's catalogue (section 4 and 4.2).

Voltage-source changes: the paper lists infinite-bus set points of 1.40, 1.20,
0.80 and 0.60 pu, which no grid-connected machine at 0.8 pu load survives with
constant field voltage (the steady-state stability limit falls below 0.8 pu at
0.6 pu). We use the ±10-20 % range the paper itself names in its contribution
list: steps of the infinite-bus voltage to 1.20, 1.10, 0.90 and 0.85 of its
pre-event value (0.85 rather than 0.80 so the constant-field machine keeps a
steady-state margin at the torque-step operating points).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from phid_ros.errors import SimulationError

KINDS: tuple[str, ...] = ("torque_step", "voltage_step", "fault", "field_step")
ROLES: tuple[str, ...] = ("identify", "validate")


@dataclass(frozen=True)
class Scenario:
    """One disturbance from the operating point.

    ``magnitude`` is ΔP_m (pu) for a torque step, the ratio V_inf,new / V_inf,0
    for a voltage step, the fault duration (s) for a fault, and the ratio V_f,new / V_f,0
    for a field step (an exciter or AVR reference step seen at the field, the plant's
    MOD-026 staged test).
    """

    name: str
    kind: str
    magnitude: float
    role: str = "identify"
    generator_damping: bool = True
    t_event: float = 1.0
    duration: float = 30.0
    fault_reactance: float = 0.04  # pu; V_t falls to ~0.21 pu, and the 200 ms fault stays stable
    description: str = ""

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise SimulationError(f"scenario {self.name}: kind {self.kind!r} not one of {KINDS}")
        if self.role not in ROLES:
            raise SimulationError(f"scenario {self.name}: role {self.role!r} not one of {ROLES}")
        if not 0.0 < self.t_event < self.duration:
            raise SimulationError(f"scenario {self.name}: t_event must lie inside (0, duration)")
        if self.kind in ("voltage_step", "field_step") and self.magnitude <= 0:
            raise SimulationError(f"scenario {self.name}: voltage ratio must be positive")
        if self.kind == "fault" and not 0.0 < self.magnitude < self.duration - self.t_event:
            raise SimulationError(f"scenario {self.name}: fault duration must be positive and end inside the run")

    @property
    def t_clear(self) -> float | None:
        return self.t_event + self.magnitude if self.kind == "fault" else None


def paper_catalogue(duration: float = 30.0) -> list[Scenario]:
    """The 15 identification scenarios of section 4 and the 3 validation scenarios of 4.2."""
    s: list[Scenario] = []
    for k, dpm in enumerate((+0.10, -0.10), start=1):
        s.append(
            Scenario(
                f"S0{k}_dampingless_torque_{dpm:+.2f}",
                "torque_step",
                dpm,
                generator_damping=False,
                duration=duration,
                description=f"dampingless torque step {dpm:+.2f} pu",
            )
        )
    for k, dpm in enumerate((+0.05, +0.10, +0.15, -0.05, -0.10), start=3):
        s.append(
            Scenario(
                f"S0{k}_torque_{dpm:+.2f}",
                "torque_step",
                dpm,
                duration=duration,
                description=f"torque step {dpm:+.2f} pu",
            )
        )
    for k, ratio in enumerate((1.20, 1.10, 0.90, 0.85), start=8):
        s.append(
            Scenario(
                f"S{k:02d}_voltage_{ratio:.2f}",
                "voltage_step",
                ratio,
                duration=duration,
                description=f"infinite-bus voltage step to {ratio:.2f} of pre-event",
            )
        )
    for k, tf in enumerate((0.050, 0.100, 0.150, 0.200), start=12):
        s.append(
            Scenario(
                f"S{k:02d}_fault_{int(tf * 1000)}ms",
                "fault",
                tf,
                duration=duration,
                description=f"three-phase terminal fault, {int(tf * 1000)} ms",
            )
        )
    return s + validation_scenarios()


def validation_scenarios(duration: float = 10.0) -> list[Scenario]:
    """Section 4.2: +20 % mechanical power (0.16 pu), dip to 0.85 pu, 150 ms fault; 10 s each."""
    return [
        Scenario(
            "V1_power_step",
            "torque_step",
            0.16,
            role="validate",
            duration=duration,
            description="mechanical power +20 % (0.16 pu)",
        ),
        Scenario(
            "V2_voltage_dip",
            "voltage_step",
            0.85,
            role="validate",
            duration=duration,
            description="infinite-bus voltage dip to 0.85 of pre-event",
        ),
        Scenario(
            "V3_fault_150ms",
            "fault",
            0.150,
            role="validate",
            duration=duration,
            description="three-phase terminal fault, 150 ms",
        ),
    ]


def find_scenario(name: str) -> Scenario:
    for sc in paper_catalogue():
        if sc.name == name or sc.name.split("_", 1)[0] == name:
            return sc
    names = ", ".join(sc.name.split("_", 1)[0] for sc in paper_catalogue())
    raise SimulationError(f"unknown scenario {name!r}; known: {names}")


def with_duration(scenario: Scenario, duration: float) -> Scenario:
    return replace(scenario, duration=duration)
