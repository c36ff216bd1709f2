"""Records database speed: `due` and `history` with 10 000 sensors and 100 000 runs, on SQLite
and on PostgreSQL (pgserver). The data is written at schema 0001 and migrated to the newest
(indexes, due dates kept on the sensors), which is timed too; the due list is also timed the
way it was before 0003 (aggregating the runs) for comparison.

Prints milliseconds (median of 7) and the ratio to a full count of the runs table measured in
the same run, so figures from noisy machines compare. Goal: due and history under 200 ms each
on SQLite with the indexes.

The records chain (migration 0007): `db verify` over 10 000 chained rows (customers and
sensors entered by the upgrade) and the quick check `run`, `certificate` and `db import` make
first (goal: under 50 ms), and the cost of one audited, chained write (`customers add`).
"""

from __future__ import annotations

import logging
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from datetime import UTC, date, datetime, timedelta
from pathlib import Path

from sqlalchemy import Engine, MetaData, insert, text

from app.io.vocabulary import RunStatus
from app.records.db.engine import make_engine, resolve_url, upgrade
from app.records.db.lab import Lab
from app.records.db.models import Customer, Sensor, SensorModel

SMOKE = "--smoke" in sys.argv[1:]  # SQLite only, 1 % of the data: checks it still runs
N_SENSORS = 100 if SMOKE else 10_000
N_RUNS = 1_000 if SMOKE else 100_000
REPEATS = 1 if SMOKE else 7
log = logging.getLogger("bench.records")


def fill(engine: Engine) -> None:
    """10 000 sensors of 20 models and 100 customers, 10 yearly runs each over ten years, the
    last ones spread over the past year (so about 1 in 12 sensors is due within 30 days)."""
    t_end = datetime(2026, 11, 1, tzinfo=UTC)
    with engine.begin() as conn:  # the tables as they are at 0001 (no later column defaults)
        reflected = MetaData()
        reflected.reflect(bind=conn)
        Customer, SensorModel, Stand, Sensor, Run = (
            reflected.tables[name]
            for name in ("customers", "sensor_models", "stands", "sensors", "runs")
        )
        conn.execute(insert(Customer), [{"name": f"C{i}", "address": ""} for i in range(100)])
        conn.execute(
            insert(SensorModel),
            [
                dict(
                    maker="M",
                    model=f"T{i}",
                    nominal_sensitivity=10.0,
                    unit="mV/(m/s^2)",
                    tolerance_percent=5,
                    frequency_min_hz=1,
                    frequency_max_hz=1e4,
                    preset="piezo",
                    level_ms2=5.0,
                )
                for i in range(20)
            ],
        )
        conn.execute(insert(Stand), [{"stand_file_sha256": "0" * 64, "name": "stand"}])
        conn.execute(
            insert(Sensor),
            [
                dict(
                    serial=f"SN-{i:05d}",
                    model_id=1 + i % 20,
                    owner_id=1 + i % 100,
                    interval_months=12,
                )
                for i in range(N_SENSORS)
            ],
        )
        rows = []
        for k in range(N_RUNS):
            sensor = 1 + k % N_SENSORS
            started = t_end - timedelta(days=365 * (9 - k // N_SENSORS) + (k * 37) % 365)
            rows.append(
                dict(
                    run_id=f"r{k}",
                    manifest_sha256=f"{k:064d}",
                    folder=f"/runs/r{k}",
                    status=RunStatus.COMPLETE.value,
                    started_utc=started,
                    dut_id=f"SN-{sensor - 1:05d}",
                    stand_id=1,
                    sensor_id=sensor,
                    reference_frequency_hz=160.0,
                    sensitivity_mv_per_ms2=10.0 + 1e-3 * (k // N_SENSORS),
                    expanded_uncertainty_mv_per_ms2=0.05,
                )
            )
        conn.execute(insert(Run), rows)


def median_ms(action: Callable[[], object]) -> float:
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        action()
        times.append(1e3 * (time.perf_counter() - start))
    return statistics.median(times)


def measure(name: str, url: str) -> None:
    engine = make_engine(resolve_url(url))
    upgrade(engine, "0001")
    start = time.perf_counter()
    fill(engine)
    fill_s = time.perf_counter() - start
    lab = Lab(engine, actor="bench")
    today = date(2026, 11, 23)

    def count() -> object:
        with engine.connect() as conn:
            return conn.execute(text("SELECT count(*) FROM runs")).scalar()

    start = time.perf_counter()
    upgrade(engine)  # 0002 indexes, 0003 due dates kept on the sensors (backfilled)
    migrate_s = time.perf_counter() - start

    def due_from_runs() -> object:  # the way before 0003: aggregate the runs every time
        with engine.connect() as conn:
            return conn.execute(
                text(
                    "SELECT s.serial, s.interval_months, max(r.started_utc) FROM sensors s "
                    "LEFT JOIN runs r ON r.sensor_id = s.id AND r.status = 'complete' "
                    "GROUP BY s.id, s.serial, s.interval_months"
                )
            ).all()

    baseline = median_ms(count)
    old = median_ms(due_from_runs)
    due = median_ms(lambda: lab.due(today=today, days=30))
    serial = f"SN-{4321 % N_SENSORS:05d}"  # a filled sensor: SN-04321 (SN-00021 in --smoke)
    history = median_ms(lambda: lab.history(serial))
    n_due = len(lab.due(today=today, days=30))
    print(
        f"{name:10s} count(runs) {baseline:6.1f} ms | due ({n_due} items) {due:6.1f} ms "
        f"({due / baseline:5.2f}x count; aggregating the runs instead: {old:6.1f} ms, "
        f"{old / baseline:5.2f}x) | "
        f"history {history:5.1f} ms ({history / baseline:5.2f}x)"
    )
    print(f"{name:10s} migration 0001 -> head with the data: {migrate_s:.1f} s")
    print(f"{name:10s} filled {N_SENSORS} sensors and {N_RUNS} runs in {fill_s:.1f} s")
    engine.dispose()


N_CHAINED = 300 if SMOKE else 10_000


def measure_chain(name: str, url: str) -> None:
    """db verify and the quick check over N_CHAINED chained rows; one chained write."""
    from app.records.db.chain_check import quick_check, verify

    engine = make_engine(resolve_url(url))
    upgrade(engine, "0006")
    with engine.begin() as conn:
        conn.execute(insert(Customer), [{"name": f"C{i}", "address": ""} for i in range(100)])
        conn.execute(
            insert(SensorModel),
            [
                dict(
                    maker="M",
                    model="T",
                    nominal_sensitivity=10.0,
                    unit="mV/(m/s^2)",
                    tolerance_percent=5,
                    frequency_min_hz=1,
                    frequency_max_hz=1e4,
                    preset="piezo",
                    level_ms2=5.0,
                )
            ],
        )
        conn.execute(
            insert(Sensor),
            [
                dict(serial=f"SN-{i:05d}", model_id=1, owner_id=1 + i % 100, interval_months=12)
                for i in range(N_CHAINED - 101)
            ],
        )
    start = time.perf_counter()
    upgrade(engine)  # 0007: every existing row entered into the chain
    enter_s = time.perf_counter() - start
    lab = Lab(engine, actor="bench")
    counter = iter(range(10**6))
    write = median_ms(lambda: lab.add_customer(f"New {next(counter)}"))
    problems = verify(engine)
    assert problems == [], problems[:3]
    full = median_ms(lambda: verify(engine))
    quick = median_ms(lambda: quick_check(engine))
    with engine.connect() as conn:
        n = conn.execute(text("SELECT count(*) FROM records_chain")).scalar()
    print(
        f"{name:10s} chain of {n} entries: db verify {full:6.1f} ms | quick check "
        f"{quick:5.1f} ms (goal < 50) | one chained write (customers add) {write:5.1f} ms | "
        f"upgrade entering {N_CHAINED} rows {enter_s:.1f} s"
    )
    engine.dispose()


def _new_database(server_url: str, name: str) -> str:
    """A new empty database on the server; its URL."""
    admin = make_engine(resolve_url(server_url))
    with admin.connect().execution_options(isolation_level="AUTOCOMMIT") as conn:
        conn.execute(text(f'CREATE DATABASE "{name}"'))
    admin.dispose()
    base, _, query = server_url.partition("?")
    return f"{base.rsplit('/', 1)[0]}/{name}?{query}"


def main() -> int:
    logging.basicConfig(level=logging.WARNING)
    with tempfile.TemporaryDirectory() as folder:
        Path(folder).chmod(0o755)  # pgserver's postgres may run as another user (root hosts)
        sqlite = [
            (measure_chain, f"sqlite:///{Path(folder) / 'chain.sqlite'}"),
            (measure, f"sqlite:///{Path(folder) / 'bench.sqlite'}"),
        ]
        if SMOKE:
            for action, url in sqlite:
                action("SQLite", url)
            return 0
        try:
            import pgserver
        except ImportError:
            pgserver = None
        server = pgserver.get_server(Path(folder) / "pg", cleanup_mode="stop") if pgserver else None
        try:
            if server is not None:  # the chain first on both engines
                measure_chain("PostgreSQL", _new_database(server.get_uri(), "chain"))
            for action, url in sqlite:
                action("SQLite", url)
            if server is None:
                print("PostgreSQL: pgserver not installed (pip install '.[test]')")
            else:
                measure("PostgreSQL", server.get_uri())
        finally:
            if server is not None:
                server.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(main())
