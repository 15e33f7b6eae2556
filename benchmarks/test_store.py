"""The results store at 10^5 cases: a finished case costs one appended line, the table is written
once at the end, and reading the store stays a matter of seconds.

A synthetic study of STORE_CASES rows (default 100000) shaped like the seed case's own row (its
~60 columns) goes through Store.add one by one, as the runner does, then is compacted and read
back. The cost per case is set beside the time of the cheapest real case (the seed's block,
solved in the same run): the store's share of a study's time is at most that ratio. For scale,
the design this replaced rewrote the whole table per case: one rewrite at the final size is timed.
"""
import os
import time

from studies.run.case import CaseSpec, run_case
from studies.run.identity import case_id
from studies.run.store import RESULTS, Store, frame_of, read_results, row_of

CASES = int(os.environ.get("STORE_CASES", 100_000))


def _rows(count: int) -> tuple[list[tuple[str, dict]], float]:
    """count synthetic (key, row) pairs like the seed case's row, and that case's own time (s)."""
    spec = CaseSpec()
    started = time.perf_counter()
    record = run_case(spec)
    case_time = time.perf_counter() - started
    template = row_of(case_id(spec), spec, {"status": "ok", "error": None, **record})
    rows = []
    for number in range(count):
        key = f"{number:016x}"
        rows.append((key, {**template, "case_id": key, "angle": float(number % 360), "err_u": 1e-7 * (1 + number)}))
    return rows, case_time


def test_store_at_a_hundred_thousand_cases(benchmark, tmp_path):
    rows, case_time = _rows(CASES)
    out = tmp_path / "out"
    out.mkdir()

    def add_all():
        store = Store(out)
        for key, row in rows:
            store.add(key, row)
        store.close()
        return store

    started = time.perf_counter()
    store = benchmark.pedantic(add_all, rounds=1, iterations=1)
    adding = time.perf_counter() - started
    started = time.perf_counter()
    log_read = len(read_results(out))                     # a report during the run: table + log
    reading_log = time.perf_counter() - started
    started = time.perf_counter()
    store.compact()
    compacting = time.perf_counter() - started
    started = time.perf_counter()
    table = read_results(out)
    reading = time.perf_counter() - started
    assert log_read == len(table) == CASES
    started = time.perf_counter()
    frame = frame_of(store.rows)
    frame.to_parquet(tmp_path / "rewrite.parquet", index=False)
    rewrite = time.perf_counter() - started
    per_case = adding / CASES
    info = {"cases": CASES, "add_per_case_s": per_case, "case_time_s": case_time,
            "store_share_of_case": per_case / case_time, "compact_s": compacting, "read_s": reading,
            "read_with_log_s": reading_log, "table_bytes": (out / RESULTS).stat().st_size,
            "old_design_rewrite_per_case_s": rewrite}
    benchmark.extra_info.update(info)
    print(f"\nstore, {CASES} cases: {1e6 * per_case:.1f} us per case ({100 * per_case / case_time:.3f}% of the "
          f"seed case's {1e3 * case_time:.1f} ms); compaction {compacting:.2f} s; read {reading:.2f} s "
          f"(with the log uncompacted {reading_log:.2f} s); the old design's rewrite of the table at this "
          f"size, per case: {rewrite:.2f} s")
