"""The assistance service under load, over real loopback HTTP against a real ``globe serve``.

Prints, with the targets of issue 10 (before: ~38 MB and ~0.8 s per household, ~6 ms per observation):
- memory: RSS growth of the server process per created HOMER+ household, after each was asked for a
  prediction (target <= 4 MB), and right after creation;
- creation: time of ``POST /households`` with a HOMER+ map and its 65 training days, its body encoded
  beforehand (target <= 0.1 s), and the server's CPU time for it (steadier on a busy machine);
- start-up: a database of 100 households with a month of observations each: time until the service
  answers (target <= 2 s), and until every household is built (replayed);
- latency and throughput of observations and predictions at 1, 4 and 8 concurrent clients.

With ``--baseline DIR`` (another checkout, e.g. ``git worktree add /tmp/before HEAD~1``, its compiled
modules built beside its sources with ``python setup.py build_ext --inplace``), the memory and load
parts also serve from that version, alternating with this one, and print each figure's ratio
(this / baseline). The households run the paper's models in both (``selection.deploy = "ngram"``
where the version has it: the cross-validated deployment runs in the background and would be timed).

Usage: python benchmarks/bench_service.py [--households 30] [--startup-households 100] [--startup-days 30]
       [--steps 218] [--only memory,startup,load] [--baseline DIR] [--repeat 1] [--data DIR]
"""

from __future__ import annotations

import datetime as dt
import json
import os
import sqlite3
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import httpx

from common import serve, setup, stop
from globe.config import GlobeConfig
from globe.service.auth import create_token
from globe.service.client import GlobeClient, household_payload
from globe.service.registry import Registry
from globe.service.store import Store
from globe.service.upload import household_from, parse_nodes

TARGET_MB, TARGET_CREATE_S, TARGET_STARTUP_S, BEFORE_OBS_MS = 4.0, 0.1, 2.0, 6.0
BASE = dt.datetime.combine(dt.date.today() - dt.timedelta(days=200), dt.time())


def cpu_s(pid: int) -> float:
    """CPU time (user + system) of a process so far: steadier than wall-clock on a busy machine."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def p95(values: list[float]) -> float:
    return sorted(values)[int(0.95 * (len(values) - 1))]


def verdict(value: float, target: float, unit: str) -> str:
    return f"target <= {target} {unit}: {'met' if value <= target else 'NOT met'}"


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


class Service:
    def __init__(self, db: Path, env: dict[str, str], src: Path | None = None) -> None:
        """``globe serve`` over ``db``: this checkout's, or the one whose sources are ``src`` (whose
        own code makes the database and its token)."""
        self.db = db
        self.env = dict(os.environ, GLOBE_LLM__BACKEND="none", GLOBE_SERVICE__MAX_CLOCK_SKEW="P400D", **env)
        if src is None:
            self.env["GLOBE_SELECTION__DEPLOY"] = "ngram"
            self.admin = create_token(db, admin=True)
            return
        self.env["PYTHONPATH"] = str(src)
        if "DeployMethod" in (src / "globe" / "config.py").read_text(encoding="utf-8"):
            self.env["GLOBE_SELECTION__DEPLOY"] = "ngram"
        made = subprocess.run([sys.executable, "-m", "globe", "token", "create", "--db", str(db), "--admin"],
                              env=self.env, capture_output=True, text=True, check=True)
        self.admin = made.stdout.strip().splitlines()[-1]

    def start(self) -> float:
        """Start; returns seconds until /health answers (process start and imports included)."""
        started = time.perf_counter()
        self.proc, self.url = serve(self.db, self.env)
        return time.perf_counter() - started

    def stop(self) -> None:
        stop(self.proc)


def memory_and_creation(homes, n: int, tmp: Path, src: Path | None = None) -> dict[str, float]:
    """Households created one by one over HTTP, then asked for a prediction each. The request body
    is JSON-encoded before the clock starts: what is timed is the request (transfer, parsing,
    validation, counting, storing), not the client's encoding, which is measured separately."""
    db = tmp / f"memory-{time.perf_counter_ns()}.sqlite3"
    svc = Service(db, {"GLOBE_SERVICE__MAX_BUILT_HOUSEHOLDS": str(n + 10), "GLOBE_SERVICE__PRELOAD": "false"}, src)
    svc.start()
    payloads = [household_payload(h) for h in homes]
    headers = {"Authorization": f"Bearer {svc.admin}", "Content-Type": "application/json"}
    with (GlobeClient(svc.url, token=svc.admin, timeout_s=120) as c,
          httpx.Client(base_url=svc.url, timeout=120, headers=headers) as http):
        c.create_household("warm-up", **payloads[0])  # first-use imports and allocations are not a household's cost
        c.prediction("warm-up")
        c.delete_household("warm-up")
        before = rss_mb(svc.proc.pid)
        times, encode, cpu = [], [], []
        for i in range(n):
            t = time.perf_counter()
            body = json.dumps({"name": f"h{i:03d}", **payloads[i % len(payloads)]}, ensure_ascii=False).encode()
            encode.append(time.perf_counter() - t)
            t, c0 = time.perf_counter(), cpu_s(svc.proc.pid)
            r = http.post("/households", content=body)
            times.append(time.perf_counter() - t)
            cpu.append(cpu_s(svc.proc.pid) - c0)
            assert r.status_code == 201, r.text
        created = rss_mb(svc.proc.pid)
        for i in range(n):
            c.prediction(f"h{i:03d}")
        after = rss_mb(svc.proc.pid)
    svc.stop()
    per, per_created = (after - before) / n, (created - before) / n
    med, enc = statistics.median(times), statistics.median(encode)
    size = statistics.mean(len(json.dumps(p)) for p in payloads) / 2**20
    print(f"memory per HOMER+ household   {per:7.2f} MB   (RSS {before:.0f} -> {after:.0f} MB over {n} households, "
          f"each asked for a prediction; {per_created:.2f} MB right after creation)   {verdict(per, TARGET_MB, 'MB')};"
          f" before ~38 MB: {38 / per:.1f}x less")
    print(f"creation per HOMER+ household {med:7.3f} s    (median of {n}; {size:.1f} MB request; "
          f"p95 {p95(times):.3f} s; server CPU {statistics.median(cpu):.3f} s; "
          f"the client's JSON encoding, not included: {enc:.3f} s)"
          f"   {verdict(med, TARGET_CREATE_S, 's')}; before ~0.8 s: {0.8 / med:.1f}x faster")
    return {"memory per household MB": per, "creation s": med}


def startup(homes, n: int, days: int, tmp: Path) -> None:
    """A database of ``n`` households with ``days`` days of observations each, written directly."""
    db = tmp / "startup.sqlite3"
    store = Store(db)
    payloads = [household_payload(h) for h in homes]
    for i in range(n):
        home, p = homes[i % len(homes)], payloads[i % len(homes)]
        h = household_from(f"h{i:03d}", parse_nodes(p["nodes"]), p["days"])
        store.add_household(h, "UTC", p["days"])
    store.close()
    created = dt.datetime.now(dt.timezone.utc)
    rows = []
    for i in range(n):
        home = homes[i % len(homes)]
        source = (home.train + home.test)[:days]
        for d, day in enumerate(source):
            for t in range(len(day)):
                time_ = BASE + dt.timedelta(days=d, minutes=day.minutes[t])
                locations = json.dumps(dict(zip(home.objects, day.locations[t])))
                rows.append((f"h{i:03d}", time_.isoformat(), day.activities[t], locations, created.isoformat()))
    db_ = sqlite3.connect(db)
    day_before = (BASE - dt.timedelta(days=1)).replace(tzinfo=dt.timezone.utc)
    db_.execute("UPDATE households SET created_at = ?", (day_before.isoformat(),))
    db_.executemany("INSERT INTO observations (household, time, activity, locations, received_at) "
                    "VALUES (?, ?, ?, ?, ?)", rows)
    db_.commit()
    db_.close()
    cfg = GlobeConfig().with_overrides(
        {"llm.backend": "none", "service.max_clock_skew": "P400D", "service.max_built_households": n})
    t0 = time.perf_counter()
    store = Store(db)
    reg = Registry(store, cfg, None)
    reg.load_all()
    ready = time.perf_counter() - t0
    reg.warm_up()
    built = time.perf_counter() - t0
    assert reg.built() == n and all(not reg.served(name).quarantined for name in reg.names())
    store.close()
    svc = Service(db, {"GLOBE_SERVICE__PRELOAD": "true"})
    process = svc.start()
    svc.stop()
    print(f"start-up, {n} households x {days} days ({len(rows)} observations, {db.stat().st_size / 2**20:.0f} MB):")
    print(f"  ready to serve (in process)   {ready:7.3f} s   {verdict(ready, TARGET_STARTUP_S, 's')}")
    print(f"  ready to serve (new process)  {process:7.3f} s   (Python start and imports included)")
    print(f"  every household built         {built:7.3f} s   "
          "(background warm-up; a request builds its household first)")


def load(homes, steps: int, tmp: Path, src: Path | None = None) -> dict[str, float]:
    svc = Service(tmp / f"load-{time.perf_counter_ns()}.sqlite3", {"GLOBE_SERVICE__PRELOAD": "false"}, src)
    figures: dict[str, float] = {}
    svc.start()
    payloads = [household_payload(h) for h in homes]
    with GlobeClient(svc.url, token=svc.admin, timeout_s=120) as c:
        for i in range(8):
            c.create_household(f"c{i}", **payloads[i % len(payloads)])
    print(f"{'clients':>7s} {'obs median ms':>14s} {'obs p95 ms':>11s} {'pred median ms':>15s} {'requests/s':>11s}"
          f"   before: ~{BEFORE_OBS_MS} ms per observation")
    offset = 0
    for clients in (1, 4, 8):
        obs_lat: list[float] = []
        pred_lat: list[float] = []
        lock = threading.Lock()

        def work(i: int, offset: int = offset, lock: threading.Lock = lock, obs_lat: list = obs_lat,
                 pred_lat: list = pred_lat) -> None:
            home = homes[i % len(homes)]
            days = home.test
            mine_o, mine_p = [], []
            with GlobeClient(svc.url, token=svc.admin) as c:
                for k in range(steps):
                    d, t = divmod(k, len(days[0]))
                    day = days[d % len(days)]
                    t = min(t, len(day) - 1)
                    when = BASE + dt.timedelta(days=offset + d, minutes=day.minutes[t])
                    s = time.perf_counter()
                    c.observe(f"c{i}", when, day.activities[t], dict(zip(home.objects, day.locations[t])))
                    mine_o.append(time.perf_counter() - s)
                    s = time.perf_counter()
                    c.prediction(f"c{i}")
                    mine_p.append(time.perf_counter() - s)
            with lock:
                obs_lat.extend(mine_o)
                pred_lat.extend(mine_p)

        threads = [threading.Thread(target=work, args=(i,)) for i in range(clients)]
        started = time.perf_counter()
        for th in threads:
            th.start()
        for th in threads:
            th.join()
        wall = time.perf_counter() - started
        offset += steps // 100 + 2
        print(f"{clients:7d} {1000 * statistics.median(obs_lat):14.2f} {1000 * p95(obs_lat):11.2f} "
              f"{1000 * statistics.median(pred_lat):15.2f} {(len(obs_lat) + len(pred_lat)) / wall:11.0f}")
        figures[f"observation ms, {clients} clients"] = 1000 * statistics.median(obs_lat)
        figures[f"prediction ms, {clients} clients"] = 1000 * statistics.median(pred_lat)
    svc.stop()
    return figures


def main() -> None:
    _, homes, args = setup(__doc__, {
        "--households": {"type": int, "default": 30, "help": "households created for the memory figure"},
        "--startup-households": {"type": int, "default": 100, "help": "households in the start-up database"},
        "--startup-days": {"type": int, "default": 30, "help": "days of observations per household there"},
        "--steps": {"type": int, "default": 218, "help": "observations (and predictions) per client"},
        "--only": {"default": "memory,startup,load", "help": "comma-separated parts to run (memory, startup, load)"},
        "--baseline": {"default": None, "help": "another checkout to compare with (memory and load parts)"},
        "--repeat": {"type": int, "default": 1, "help": "runs of each version, alternated (the median is compared)"},
    })
    parts = set(args.only.split(","))
    versions: list[tuple[str, Path | None]] = [("this", None)]
    if args.baseline:
        versions.append(("baseline", Path(args.baseline).resolve() / "src"))
    print(f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} (figures are wall-clock)")
    found: dict[str, dict[str, list[float]]] = {name: {} for name, _ in versions}
    with tempfile.TemporaryDirectory() as tmp:
        if "startup" in parts:
            startup(homes, args.startup_households, args.startup_days, Path(tmp))
        for _ in range(args.repeat):
            for name, src in versions:
                print(f"-- {name} version" + (f" ({src})" if src else ""))
                figures: dict[str, float] = {}
                if "memory" in parts:
                    figures |= memory_and_creation(homes, args.households, Path(tmp), src)
                if "load" in parts:
                    figures |= load(homes, args.steps, Path(tmp), src)
                for key, value in figures.items():
                    found[name].setdefault(key, []).append(value)
    if args.baseline:
        print(f"{'figure':32s} {'this':>9s} {'baseline':>9s} {'ratio':>6s}   (median of {args.repeat} runs each)")
        for key, values in found["this"].items():
            mine, theirs = statistics.median(values), statistics.median(found["baseline"].get(key, [float("nan")]))
            print(f"{key:32s} {mine:9.3f} {theirs:9.3f} {mine / theirs:6.2f}")


if __name__ == "__main__":
    main()
