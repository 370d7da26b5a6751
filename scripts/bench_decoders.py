#!/usr/bin/env python3
"""Decoding speed of ebiv against the other public decoders, on the same files, in one run.

Makes a recording of the `paper-rate` scene with `ebiv simulate` (EVT 3.0), converts it with
`ebiv convert` to EVT 2.0 and AEDAT 4.0 (LZ4), creates a throw-away virtual environment with
the other decoders from PyPI (expelliarmus, faery, dv-processing) and the ebiv Python package,
and times every decoder on every file from Python. Each decoder hands every event of the file
to Python as NumPy arrays through its own fastest reading call (batches or one array). The
process is pinned to one CPU, so every decoder runs on a single core whatever threads it
starts. The decoders take turns, in a rotating order, for `--repeat` rounds; each one's best
time counts. Prints a Markdown table of M events/s and ebiv's ratio to the fastest other
decoder of each format.

    python3 scripts/bench_decoders.py              # from the workspace root, after
                                                   # cargo build --release -p ebiv-cli

Not part of `.ci/run`: it downloads packages and compiles the ebiv package (minutes).
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PEERS = ["expelliarmus", "faery", "dv-processing"]


def outer(args):
    """Recordings, the virtual environment, then the timing run inside it."""
    work = Path(args.workdir or tempfile.mkdtemp(prefix="ebiv-decoders-"))
    work.mkdir(parents=True, exist_ok=True)
    ebiv_bin = Path(args.ebiv_bin)
    if not ebiv_bin.exists():
        sys.exit(f"{ebiv_bin} not found: run `cargo build --release -p ebiv-cli` or give --ebiv-bin")
    files = {
        "EVT 3.0": work / "paper_evt3.raw",
        "EVT 2.0": work / "paper_evt2.raw",
        "AEDAT 4.0 (LZ4)": work / "paper.aedat4",
    }
    if not files["EVT 3.0"].exists():
        run([ebiv_bin, "simulate", "--example", "paper-rate", "--duration", args.duration,
             "-o", files["EVT 3.0"]])
    if not files["EVT 2.0"].exists():
        run([ebiv_bin, "convert", files["EVT 3.0"], files["EVT 2.0"], "--output-encoding", "evt2"])
    if not files["AEDAT 4.0 (LZ4)"].exists():
        run([ebiv_bin, "convert", files["EVT 3.0"], files["AEDAT 4.0 (LZ4)"]])

    venv = Path(args.venv) if args.venv else work / "venv"
    python = venv / "bin" / "python"
    if not python.exists():
        run([sys.executable, "-m", "venv", venv])
        run([python, "-m", "pip", "install", "-q", "numpy", *PEERS])
        run([python, "-m", "pip", "install", "-q", args.ebiv_package])
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
               MKL_NUM_THREADS="1", RAYON_NUM_THREADS="1")
    inner_args = [python, __file__, "--inner", json.dumps({k: str(v) for k, v in files.items()}),
                  "--repeat", str(args.repeat)]
    try:
        subprocess.run([str(a) for a in inner_args], check=True, env=env)
    finally:
        if not args.workdir and not args.venv:
            shutil.rmtree(work)


def run(command):
    print("$", " ".join(str(c) for c in command), file=sys.stderr)
    subprocess.run([str(c) for c in command], check=True)


# --- the timing run, inside the virtual environment -------------------------------------------

def decoders(fmt):
    """(name, call) for every decoder of `fmt`; a call reads a path, returns its event count."""
    import numpy as np  # noqa: F401 (every decoder hands out NumPy arrays)

    def ebiv_batches(path):
        import ebiv
        n = 0
        for t, _x, _y, _p in ebiv.open(path):
            n += len(t)
        return n

    def faery_batches(path):
        import faery
        n = 0
        for packet in faery.events_stream_from_file(path):
            n += len(packet)
        return n

    def expelliarmus_whole(encoding):
        def call(path):
            from expelliarmus import Wizard
            return len(Wizard(encoding=encoding).read(path))
        return call

    def dv_batches(path):
        import dv_processing as dv
        recording = dv.io.MonoCameraRecording(path)
        n = 0
        while recording.isRunning():
            batch = recording.getNextEventBatch()
            if batch is None:
                break
            n += len(batch.numpy())
        return n

    table = {
        "EVT 3.0": [("ebiv", ebiv_batches), ("expelliarmus", expelliarmus_whole("evt3")),
                    ("faery", faery_batches)],
        "EVT 2.0": [("ebiv", ebiv_batches), ("expelliarmus", expelliarmus_whole("evt2")),
                    ("faery", faery_batches)],
        "AEDAT 4.0 (LZ4)": [("ebiv", ebiv_batches), ("dv-processing", dv_batches),
                            ("faery", faery_batches)],
    }
    return table[fmt]


def inner(args):
    files = json.loads(args.inner)
    cpu = min(os.sched_getaffinity(0))
    os.sched_setaffinity(0, {cpu})
    rows = []
    for fmt, path in files.items():
        entries = decoders(fmt)
        counts = {name: call(path) for name, call in entries}  # warm-up, and the counts agree
        if len(set(counts.values())) != 1:
            sys.exit(f"{fmt}: the decoders disagree on the event count: {counts}")
        events = next(iter(counts.values()))
        best = {name: float("inf") for name, _ in entries}
        for round_ in range(args.repeat):
            k = round_ % len(entries)
            for name, call in entries[k:] + entries[:k]:
                start = time.perf_counter()
                call(path)
                best[name] = min(best[name], time.perf_counter() - start)
        rate = {name: events / best[name] * 1e-6 for name in best}
        peers = {n: r for n, r in rate.items() if n != "ebiv"}
        fastest = max(peers, key=peers.get)
        rows.append((fmt, events, rate, fastest))

    print(f"\nevents per file: {rows[0][1]}; best of {args.repeat} alternating runs per decoder, "
          f"one CPU (CPU {cpu}); M events/s\n")
    print("| format | ebiv | other decoders | ebiv / fastest other |")
    print("|---|---|---|---|")
    for fmt, _, rate, fastest in rows:
        others = ", ".join(f"{n} {r:.0f}" for n, r in sorted(rate.items(), key=lambda kv: -kv[1])
                           if n != "ebiv")
        print(f"| {fmt} | {rate['ebiv']:.0f} | {others} | {rate['ebiv'] / rate[fastest]:.2f}× {fastest} |")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ebiv-bin", default=str(ROOT / "target" / "release" / "ebiv"),
                        help="the ebiv program that makes the recordings")
    parser.add_argument("--ebiv-package", default=str(ROOT / "crates" / "ebiv-py"),
                        help="what pip installs as the ebiv package (the source tree, or a wheel)")
    parser.add_argument("--duration", default="310ms",
                        help="length of the simulated recording (310ms: about 6.2 M events)")
    parser.add_argument("--repeat", type=int, default=7, help="timed rounds per decoder")
    parser.add_argument("--workdir", help="where recordings (and the environment) go; "
                        "kept and reused; default: a new temporary directory")
    parser.add_argument("--venv", help="use or create the virtual environment here")
    parser.add_argument("--inner", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.inner:
        inner(args)
    else:
        outer(args)


if __name__ == "__main__":
    main()
