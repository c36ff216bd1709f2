"""Shared test set-up: isolated Qt settings; opt-in real-hardware options
(`pytest tests/hardware --daq-device Dev1 --visa-resource ...`)."""

from __future__ import annotations

import atexit
import gc
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from sqlalchemy import Engine

# before numpy is imported (here, in every xdist worker, and in every process a test starts,
# which inherits the environment): OpenBLAS on one thread. The suite runs one worker per core;
# a second BLAS thread per worker only spins waiting for work (a run's matrix products are
# small), and that spinning was about 40 % of a simulated run's CPU seconds in a test
# (tests/app/procedure/test_procedure.py::test_simulated_runs_recover_the_truth: 7.4-7.9 CPU s
# with OpenBLAS's default of 2 threads, 4.1-4.2 with 1). `OPENBLAS_NUM_THREADS=2 pytest ...`
# still chooses otherwise.
for _blas_threads in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_blas_threads, "1")

# before anything creates a QSettings: the whole session's Qt settings live in a temporary
# folder, never in the user's ~/.config (tests also get one folder each, below)
_CONFIG_HOME = tempfile.mkdtemp(prefix="accelcal-tests-config-")
os.environ["XDG_CONFIG_HOME"] = _CONFIG_HOME
atexit.register(shutil.rmtree, _CONFIG_HOME, ignore_errors=True)
# and the user data directory (records database, stored responses) likewise, for fixtures of
# module or session scope too: a records file in the user's own ~/.local/share would put
# every run and certificate of the session under those records (app.records.db.engine)
_DATA_HOME = tempfile.mkdtemp(prefix="accelcal-tests-data-")
os.environ["XDG_DATA_HOME"] = _DATA_HOME
atexit.register(shutil.rmtree, _DATA_HOME, ignore_errors=True)


def _relative(item: pytest.Item) -> str:
    """The test's file relative to tests/, as posix."""
    root = Path(__file__).resolve().parent
    return Path(str(item.path)).resolve().relative_to(root).as_posix()


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--daq-device", default=None, help="NI-DAQmx device for *_with_device tests")
    parser.addoption("--visa-resource", default=None, help="VISA resource of a measuring amplifier")


@pytest.fixture()
def daq_device(request: pytest.FixtureRequest) -> str:
    device = request.config.getoption("--daq-device")
    if device is None:
        pytest.skip("real-hardware test: give --daq-device to run it")
    return device


@pytest.fixture()
def visa_resource(request: pytest.FixtureRequest) -> str:
    resource = request.config.getoption("--visa-resource")
    if resource is None:
        pytest.skip("real-hardware test: give --visa-resource to run it")
    return resource


@pytest.fixture(scope="session", autouse=True)
def _records_key(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """One records key (app.records.db.records_key) per test process, set before any session
    fixture makes records: the databases the tests copy from one migrated template, and the
    session's labs, carry heads signed with it. Never the user's own key."""
    with pytest.MonkeyPatch.context() as patch:
        key = tmp_path_factory.getbasetemp() / "records-key" / "records-key.pem"
        patch.setenv("ACCELCAL_RECORDS_KEY", str(key))
        patch.delenv("ACCELCAL_RECORDS_PUBLIC_KEY", raising=False)
        patch.delenv("ACCELCAL_RECORDS_KEY_PASSWORD", raising=False)
        patch.delenv("ACCELCAL_TRUST", raising=False)
        yield


@pytest.fixture(autouse=True)
def _qt_garbage_collected_on_the_main_thread(request: pytest.FixtureRequest) -> Iterator[None]:
    """A test with Qt objects (qtbot, qapp) runs with automatic garbage collection off, and its
    garbage is collected here, on the main thread, when it ends. Otherwise a cycle holding a Qt
    object is left for the next collection, which may start in any thread that allocates (a
    web request's, a run's) and free the object there: the process then crashes or hangs (CI
    saw a worker killed by SIGSEGV inside a collection started by a web test's request
    thread). The window does the same while open: app/gui/collector.py."""
    if not {"qtbot", "qapp"} & set(request.fixturenames):
        yield
        return
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        gc.collect()
        if was_enabled:
            gc.enable()


@pytest.fixture(autouse=True)
def _isolated_data_dir(tmp_path_factory: pytest.TempPathFactory, monkeypatch) -> None:
    """Each test gets its own user data directory (platformdirs honours XDG_DATA_HOME): the
    stand's stored responses of one test never change how another one runs, and nothing is
    written to the user's own ~/.local/share."""
    home = _own_folder(tmp_path_factory, "data-home")
    monkeypatch.setenv("XDG_DATA_HOME", str(home))
    # ... except the custom plans' optimised phases (app.procedure.phase_store), which depend
    # only on the plan: one cache per test process, so a plan is optimised once per session,
    # not once per test (the store checks every entry it reads; tests of the store itself give
    # it a data directory of their own)
    (home / "accelcal").mkdir()
    (home / "accelcal" / "phases").symlink_to(_shared_phase_cache(tmp_path_factory))


def _own_folder(tmp_path_factory: pytest.TempPathFactory, prefix: str) -> Path:
    """A new empty folder of this test's, under the process's base temporary folder but not
    in it: `tmp_path_factory.mktemp` numbers a folder by listing the base folder, so the two
    folders every test got there (next to its tmp_path) made each test's listing longer
    (quadratic: about 9 CPU s per 1200 tests in one worker)."""
    parent = tmp_path_factory.getbasetemp() / f"per-test-{prefix}"
    parent.mkdir(exist_ok=True)
    return Path(tempfile.mkdtemp(prefix=f"{prefix}-", dir=parent))


def _shared_phase_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """This test process's one folder of cached phases (made on first use)."""
    folder = tmp_path_factory.getbasetemp() / "shared-phase-cache"
    folder.mkdir(exist_ok=True)
    return folder


@pytest.fixture(autouse=True)
def _isolated_qt_settings(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Each test gets its own QSettings store (no window geometry, DUT or stand file carried
    from one test to the next, nothing read from or written to the user's own settings)."""
    try:
        from PySide6.QtCore import QSettings
    except ImportError:  # tests without Qt
        return
    folder = _own_folder(tmp_path_factory, "qsettings")
    for fmt in (QSettings.Format.NativeFormat, QSettings.Format.IniFormat):
        QSettings.setPath(fmt, QSettings.Scope.UserScope, str(folder))


@pytest.fixture(scope="session")
def complete_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One complete simulated run for the whole session (piezo DUT SN-42, 4 periods, tolerance
    5 %, technician T. Ester): its run folder. Tests that need a runs root of their own (a
    fresh certificate register) copy it; nothing else may change it."""
    from app.io.vocabulary import RunStatus
    from app.procedure.run import RunRequest, execute

    out = tmp_path_factory.mktemp("runs")
    finished = execute(
        RunRequest(
            dut="piezo",
            dut_id="SN-42",
            periods=4,
            tolerance_percent=5.0,
            out=out,
            technician="T. Ester",  # the certificate's Prepared by (issue 27)
        )
    )
    assert finished.status == RunStatus.COMPLETE
    return out / str(finished.record.run_id)


@pytest.fixture(scope="session")
def sweep_run(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """One amplitude sweep for the whole session (capacitive DUT SN-7, whose cubic term
    compresses with level; 3 periods, seed 2, at 3, 5 and 7 m/s^2): its app.procedure.sweep
    Sweep, whose runs and summary live under one runs root. Tests copy; nothing may change it."""
    from app.procedure.run import RunRequest
    from app.procedure.sweep import run_sweep

    out = tmp_path_factory.mktemp("sweep")
    sweep = run_sweep(
        RunRequest(dut="capacitive", dut_id="SN-7", periods=3, seed=2, out=out), [3.0, 5.0, 7.0]
    )
    assert sweep.complete
    return sweep


@pytest.fixture(scope="session")
def aborted_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One aborted simulated run for the whole session (piezo, 4 periods, the DAQ lost 15 s in):
    its run folder, as the procedure leaves it. Tests copy it; nothing may change it."""
    from app.io.vocabulary import RunStatus
    from app.procedure.run import RunRequest, execute
    from sim.stand import Fault

    out = tmp_path_factory.mktemp("aborted")
    finished = execute(RunRequest(periods=4, faults=(Fault("device-lost", 15.0),), out=out))
    assert finished.status == RunStatus.ABORTED
    return out / str(finished.record.run_id)


# --- records databases: migrated once per process, copied per test (tests/records_db.py) -----


@pytest.fixture(scope="session")
def postgres_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """The URL of a PostgreSQL server private to this test process (pgserver, in a temporary
    folder). With CI=true a PostgreSQL that cannot start fails the suite."""
    from tests.pg_server import start_pgserver

    try:
        # tmp_path_factory is per xdist worker: each worker has a server of its own
        server = start_pgserver(tmp_path_factory.mktemp("pg"))
    except Exception as exc:  # no wheel, no start
        if os.environ.get("CI") == "true":
            pytest.fail(f"PostgreSQL could not start in CI: {exc}")
        pytest.skip(f"PostgreSQL could not start: {exc}")
    try:
        yield server.get_uri()
    finally:
        server.cleanup()


@pytest.fixture(params=["sqlite", "postgresql"])
def empty_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """The URL of an empty database (no schema) on each engine."""
    from app.records.db.engine import resolve_url
    from tests.records_db import postgres_database

    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'records.sqlite'}"
    return resolve_url(postgres_database(request.getfixturevalue("postgres_server")))


@pytest.fixture(params=["sqlite", "postgresql"])
def migrated_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """The URL of a database at the newest schema on each engine: a copy of one migrated once
    (an SQLite file; a PostgreSQL template database)."""
    from app.records.db.engine import resolve_url
    from tests.records_db import migrated_postgres_template, new_records, postgres_database

    if request.param == "sqlite":
        return resolve_url(new_records(tmp_path / "records.sqlite"))
    server = request.getfixturevalue("postgres_server")
    return resolve_url(postgres_database(server, template=migrated_postgres_template(server)))


@pytest.fixture
def engine(migrated_url: str) -> Iterator[Engine]:
    """An engine on a database at the newest schema, on each engine."""
    from app.records.db.engine import make_engine

    engine = make_engine(migrated_url)
    yield engine
    engine.dispose()


@pytest.fixture
def records_url(tmp_path: Path) -> str:
    """The URL of a new SQLite records database at the newest schema, tmp_path/records.sqlite
    (a copy of the one migrated once per process)."""
    from tests.records_db import new_records

    return new_records(tmp_path / "records.sqlite")


# The fast tier (`make test-fast`: dsp, units, CLI parsing) leaves out whatever runs a
# calibration, a subprocess, the GUI, a database or a Monte Carlo study. Whole files are marked
# here by path, tests of other files by the fixtures they use (a completed calibration run, the
# Qt window); single tests elsewhere carry @pytest.mark.integration / slow themselves.
INTEGRATION_PATHS = (
    "app/records/db/",  # SQLite and PostgreSQL records databases, migrations, concurrent writers
    "web/",  # the web view on a records database, a browser
    "app/certificate/test_verify.py",  # runs, signed certificates, special files
    "app/certificate/test_sign.py",  # a throwaway CA, signed certificates
    "app/procedure/test_impact.py",  # records, runs re-analysed in a process pool
    "app/cli/test_certificate.py",  # runs and their certificates
    "app/certificate/test_pdf.py",  # fixture runs, PDFs
    "app/certificate/test_dcc.py",  # a fixture run, its certificate and DCC
    "app/cli/test_analyze.py",  # calibration runs and recordings end to end
    "app/records/test_legacy_formats.py",  # a stored run certified, a stored database upgraded
    "app/procedure/test_procedure.py",  # procedure runs, SIGTERM on a subprocess
    "app/cli/test_analyze_examples.py",  # simulations and analyses of the README's examples
    "app/records/test_run_folder.py",  # run folders of real runs
    "app/records/test_run_folder_integrity.py",  # runs, concurrent subprocesses
    "app/procedure/test_procedure_safety.py",  # runs with faults, signals to subprocesses
    "app/cli/test_simulate.py",  # simulated recordings end to end
    "app/cli/test_startup.py",  # fresh interpreters
    "app/test_version.py",  # git and a fresh interpreter
    "gui/",  # the Qt window, live runs, soak
    "hostile/test_processes.py",  # subprocesses
)

INTEGRATION_FIXTURES = frozenset({"complete_run", "aborted_run", "sweep_run", "qtbot"})


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark the tests of INTEGRATION_PATHS, and those using INTEGRATION_FIXTURES, `integration`;
    then put the tests marked `long` first (a stable sort: otherwise in collection order), so
    that pytest-xdist deals them out at the start and the suite never ends waiting for one of
    them on a single worker."""
    for item in items:
        relative = _relative(item)
        fixtures = set(getattr(item, "fixturenames", ()))
        if relative.startswith(INTEGRATION_PATHS) or fixtures & INTEGRATION_FIXTURES:
            item.add_marker(pytest.mark.integration)
    items.sort(key=lambda item: item.get_closest_marker("long") is None)
