"""The words stored files spell, each defined once as a StrEnum (members are the strings
themselves, so HDF5 attributes, results.json and the database hold the same text as before):
how a run ended (`RunStatus`), its excitation (`Mode`) and the stand's acquisition
(`Backend`). Importable light (no numpy, h5py).

Here, at the bottom of app/, because the recording (app.io.hdf5), the stored stand responses
(app.stand.response), the run record and folder (app.records) and the procedure all use them.
"""

from __future__ import annotations

from enum import StrEnum


class RunStatus(StrEnum):
    """How a run, and its recording, ended."""

    COMPLETE = "complete"
    ABORTED = "aborted"
    INCOMPLETE = "incomplete"  # a recording with no end mark: cut off, or written before marks


class Mode(StrEnum):
    """The excitation of a run: all lines at once, or one line at a time."""

    MULTISINE = "multisine"
    STEPPED_SINE = "stepped-sine"


class Backend(StrEnum):
    """The data acquisition behind a stand: the built-in simulator or NI-DAQmx hardware
    (a stand file's [daq] backend)."""

    SIM = "sim"
    NIDAQMX = "nidaqmx"
