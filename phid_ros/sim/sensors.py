"""Sensor models per channel: white Gaussian noise, quantisation, sampling, seedable.

Defaults are instrument grade: PT/CT 0.2-0.3 % of rated, speed encoder 1e-5 pu,
PMU angles 1 mrad. Quantisation steps are powers of two, as a real ADC's LSB
over a power-of-two full scale is; it also keeps the shipped bags compressible.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from phid_ros.errors import SimulationError


@dataclass(frozen=True)
class ChannelSensor:
    noise_std: float  # absolute, in the channel's unit (pu or rad)
    lsb: float  # quantisation step; 0 disables

    def __post_init__(self) -> None:
        if self.noise_std < 0 or self.lsb < 0:
            raise SimulationError(f"sensor noise and LSB must be non-negative, got {self}")


DEFAULT_CHANNEL_SENSORS: dict[str, ChannelSensor] = {
    # PT/CT
    "v_t": ChannelSensor(0.002, 2.0**-15),
    "i_d": ChannelSensor(0.003, 2.0**-13),
    "i_q": ChannelSensor(0.003, 2.0**-13),
    "p_e": ChannelSensor(0.003, 2.0**-13),
    "q_e": ChannelSensor(0.003, 2.0**-13),
    # speed encoder and shaft torque transducer
    "omega": ChannelSensor(1e-5, 2.0**-20),
    "p_m": ChannelSensor(0.002, 2.0**-14),
    # PMU angles
    "theta_t": ChannelSensor(1e-3, 2.0**-16),
    "delta": ChannelSensor(1e-3, 2.0**-16),
    # excitation system
    "v_f": ChannelSensor(0.005, 2.0**-13),
}


@dataclass(frozen=True)
class SensorModel:
    channels: Mapping[str, ChannelSensor] = field(default_factory=lambda: dict(DEFAULT_CHANNEL_SENSORS))
    seed: int = 0
    noiseless: bool = False

    def measure(
        self, truth: Mapping[str, NDArray[np.float64]], *, stream_seed: int = 0
    ) -> dict[str, NDArray[np.float64]]:
        """Noisy, quantised copies of the true signals; same seeds give the same samples."""
        out: dict[str, NDArray[np.float64]] = {}
        for index, (name, values) in enumerate(sorted(truth.items())):
            sensor = self.channels.get(name)
            if sensor is None:
                raise SimulationError(f"no sensor model for channel {name!r}")
            x = np.array(values, dtype=float)
            if not self.noiseless:
                rng = np.random.default_rng([self.seed, stream_seed, index])
                x = x + rng.normal(0.0, sensor.noise_std, size=x.shape)
                if sensor.lsb > 0:
                    x = np.round(x / sensor.lsb) * sensor.lsb
            out[name] = x
        return out
