"""The simulated fixture as the simulated stand codes to it (issue 36): the `FixtureMotion`
Protocol, the rigid fixture (every position moves with the reference axis, no crosstalk), and
the one place the stand file's fixture physics is chosen (`fixture_motion`).

The physics of a real fixture (rocking modes, bending: sim.fixture.FixtureModel) satisfies
the Protocol structurally. The simulated stand applies both per period in the frequency
domain (`apply_motion`, `apply_crosstalk`), exact for the periodic drive in steady state.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class FixtureMotion(Protocol):
    """How a fixture moves the positions on it, and how its channels leak into each other."""

    def motion_ratio(self, position: str, frequency_hz: np.ndarray) -> np.ndarray:
        """Complex axial acceleration at `position` over that at the reference axis."""
        ...

    def crosstalk(self, frequency_hz: np.ndarray, channels: Sequence[str]) -> np.ndarray:
        """Complex (F, n, n) mixing of the n input channels' voltages (v_out = C @ v_in;
        C[:, i, i] = 1)."""
        ...


class RigidFixture:
    """A rigid fixture: motion ratio 1 at every position, no crosstalk (the default when the
    stand file has no [simulation.fixture])."""

    rigid = True  # the stand skips the frequency-domain steps (identity)

    def motion_ratio(self, position: str, frequency_hz: np.ndarray) -> np.ndarray:
        """1 at every frequency (complex)."""
        return np.ones(np.shape(frequency_hz), dtype=complex)

    def crosstalk(self, frequency_hz: np.ndarray, channels: Sequence[str]) -> np.ndarray:
        """The identity for every frequency: (F, n, n)."""
        n = len(channels)
        return np.broadcast_to(np.eye(n, dtype=complex), (np.size(frequency_hz), n, n)).copy()


def fixture_motion(stand_config: Mapping[str, Any]) -> FixtureMotion:
    """The simulated fixture of a stand file (`stand_config`: its tables as read): the
    physics of its [simulation.fixture] with the [[fixture.position]] geometry
    (sim.fixture.FixtureModel.from_stand; InputRefused naming a bad key), else the rigid
    fixture."""
    from sim.fixture import FixtureModel

    model = FixtureModel.from_stand(stand_config)
    return RigidFixture() if model is None else model


def is_rigid(fixture: FixtureMotion) -> bool:
    """Whether `fixture` is known to be rigid (its steps may be skipped)."""
    return bool(getattr(fixture, "rigid", False))


def apply_motion(
    block: np.ndarray, fixture: FixtureMotion, position: str, sample_rate_hz: float
) -> np.ndarray:
    """One period of a DUT's noise-free output (V) at `position`, from its output had it moved
    with the reference axis: each DFT bin times the position's motion ratio (a real signal:
    the negative frequencies follow)."""
    spectrum = np.fft.rfft(block)
    frequency = np.fft.rfftfreq(block.size, 1.0 / sample_rate_hz)
    spectrum *= fixture.motion_ratio(position, frequency)
    return np.fft.irfft(spectrum, n=block.size)


def apply_crosstalk(
    blocks: Mapping[str, np.ndarray], fixture: FixtureMotion, sample_rate_hz: float
) -> dict[str, np.ndarray]:
    """The input channels' periods (V) after the fixture's crosstalk, v_out = C(f) @ v_in at
    every DFT bin."""
    names = list(blocks)
    n = next(iter(blocks.values())).size
    spectra = np.stack([np.fft.rfft(blocks[name]) for name in names])  # (channels, F)
    frequency = np.fft.rfftfreq(n, 1.0 / sample_rate_hz)
    mixing = fixture.crosstalk(frequency, names)  # (F, channels, channels)
    mixed = np.einsum("fij,jf->if", mixing, spectra)
    return {name: np.fft.irfft(mixed[i], n=n) for i, name in enumerate(names)}
