"""Where `Simulator.run`'s wall time goes on the two cores (corridor, poses 5-44).

Per run: wall and CPU time per measurement (perfect use of two cores: wall = CPU / 2),
the time the rendering (main) thread waited for the next pose's preparation, and
how many of the process's threads were runnable (Linux ``/proc``: sampled every
millisecond by a child process, so the sampling takes no GIL here), with the
machine's idle share and load average over the same time.  On a loaded machine a
runnable thread may be waiting for a core that another process holds: fewer than
two runnable threads is where a core would idle on a machine of our own.

    python -m benchmarks.pipeline [--runs 3] [--ahead 1,2]

``--ahead``: the values of :data:`acousim.simulator.PREPARE_AHEAD` run in turn
(alternating, the same simulator), each run printed with its value.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

SCENE = Path(__file__).resolve().parent.parent / "scenes" / "corridor.toml"
POSES = range(5, 45)


def _machine_cpu() -> tuple[int, int]:
    """(idle + iowait, total) jiffies of the machine so far."""
    with open("/proc/stat") as f:
        v = [int(x) for x in f.readline().split()[1:]]
    return v[3] + v[4], sum(v)


def _runnable(pid: int) -> int:
    """How many of process `pid`'s threads are running or waiting for a core."""
    n = 0
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            with open(f"/proc/{pid}/task/{tid}/stat") as f:
                stat = f.read()
        except OSError:  # the thread ended meanwhile
            continue
        n += stat[stat.rindex(")") + 2] == "R"
    return n


def sample(pid: int, where: Path) -> None:
    """Count `pid`'s runnable threads every millisecond from when the file ``go``
    exists in `where` until ``stop`` does; write to ``out.json`` there the shares of
    samples with 0, 1, 2, 3+ runnable and the machine's idle share."""
    counts: Counter[int] = Counter()
    stop, go = where / "stop", where / "go"
    while not go.exists():
        time.sleep(0.0005)
    idle0, total0 = _machine_cpu()
    while not stop.exists():
        try:
            counts[min(_runnable(pid), 3)] += 1
        except FileNotFoundError:  # the process ended
            break
        time.sleep(0.001)
    idle1, total1 = _machine_cpu()
    n = max(1, sum(counts.values()))
    shares = {str(k): counts[k] / n for k in range(4)}
    idle = (idle1 - idle0) / max(1, total1 - total0)
    (where / "out.json").write_text(json.dumps({"runnable": shares, "idle": idle}))


def _timed_record(sim) -> list[float]:
    """Wrap `sim`'s render of a prepared pose (this instance only) to add up its wall time."""
    spent = [0.0]
    record = sim._record

    def timed(*args, **kwargs):
        t = time.perf_counter()
        try:
            return record(*args, **kwargs)
        finally:
            spent[0] += time.perf_counter() - t

    sim._record = timed
    return spent


def one_run(sim, spent: list[float], where: Path) -> dict:
    """`sim.run(POSES)` watched by a sampling child process."""
    stop, go, out = where / "stop", where / "go", where / "out.json"
    stop.unlink(missing_ok=True)
    go.unlink(missing_ok=True)
    child = subprocess.Popen(
        [sys.executable, "-m", "benchmarks.pipeline", "--sample", str(os.getpid()), str(where)]
    )
    sim.tracer.forget()
    spent[0] = 0.0
    go.touch()  # the child waits for it (started, its Python loaded)
    t, c = time.perf_counter(), time.process_time()
    sim.run(POSES, processes=1)  # the threads' pipeline, in this process
    wall, cpu = time.perf_counter() - t, time.process_time() - c
    stop.touch()  # the sampling stops within a millisecond of the run's end
    child.wait()
    seen = json.loads(out.read_text())
    n = len(POSES)
    return {"wall": wall / n, "cpu": cpu / n, "waited": (wall - spent[0]) / n, **seen}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3, help="runs (of each --ahead value)")
    ap.add_argument("--ahead", default="", help="PREPARE_AHEAD values, comma-separated")
    ap.add_argument("--sample", nargs=2, metavar=("PID", "DIR"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.sample:
        sample(int(a.sample[0]), Path(a.sample[1]))
        return
    from acousim.process import configure

    configure()
    from acousim import simulator
    from acousim.scene import load_scene
    from acousim.simulator import Simulator

    values = [int(v) for v in a.ahead.split(",")] if a.ahead else [simulator.PREPARE_AHEAD]

    sim = Simulator(load_scene(SCENE))
    sim.run([0, 1])  # compiled kernels, caches
    spent = _timed_record(sim)
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(a.runs * len(values)):
            simulator.PREPARE_AHEAD = values[k % len(values)]
            r = one_run(sim, spent, Path(tmp))
            load = os.getloadavg()[0]
            shares = " ".join(f"{n}:{v:.2f}" for n, v in r["runnable"].items())
            print(
                f"ahead {simulator.PREPARE_AHEAD}: wall {r['wall'] * 1e3:.1f} ms, "
                f"CPU {r['cpu'] * 1e3:.1f} ms per measurement "
                f"(CPU/wall {r['cpu'] / r['wall']:.2f}, {1 / r['wall']:.1f}/s); rendering "
                f"thread waited {r['waited'] * 1e3:.1f} ms; runnable threads {shares}; "
                f"machine idle {r['idle']:.2f}, load {load:.1f}",
                flush=True,
            )


if __name__ == "__main__":
    main()
