"""Kill each stage at a random moment, run the same command again, compare with an uninterrupted run.

For every stage (``render``, ``detect``, ``estimate``, ``evaluate``, ``pipeline``) and
``--trials`` times: the stage's input is copied from a reference run, the stage's command
starts, a SIGKILL hits its process group at a uniformly random moment within the
stage's reference duration, and the same command runs again to the end. Its outputs
must equal the reference run's: images and camera files byte for byte, tables value for
value (``pandas.testing``; columns of timings excepted), JSON files key for key (times
excepted). Printed: per stage, trials, kills that landed before the stage finished,
reruns that failed, and outputs that differ (both must be 0).

Usage::

    .venv/bin/python benchmarks/kill_resume.py [--trials 20] [--seed 0] [--work /tmp/kill_resume]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

CONFIG = """\
name: killtest
seed: 3
cameras: [{preset: 8mp, size: [320, 180]}]
heights_m: [30, 45]
lighting: [night, day]
motion: {source: fixed, attitudes_deg: [[0, 0, 0], [3, -2, 10], [-2, 4, 30]]}
sensor: {bit_depth: 8}
scene: {shading: flat, texture_px: 256}
"""

DECKPOSE = [sys.executable, "-m", "deckpose"]
#: Keys and columns that hold times or machine facts, not results.
VOLATILE = ("time", "seconds", "_s_", "elapsed", "started", "finished", "created", "host", "duration")


def commands(cfg: Path, run: Path) -> dict[str, list[str]]:
    return {
        "render": [*DECKPOSE, "render", str(cfg), str(run), "--resume", "--no-progress"],
        "detect": [*DECKPOSE, "detect", str(run), "--no-progress"],
        "estimate": [*DECKPOSE, "estimate", "--run", str(run), "--detector", "cog", "--method", "pnp"],
        "evaluate": [*DECKPOSE, "evaluate", str(run), "--no-mcap"],
        "pipeline": [*DECKPOSE, "pipeline", str(cfg), str(run), "--method", "pnp", "--no-mcap",
                     "--no-progress"],
    }


#: What each stage needs before it runs (copied from the reference run) and what it writes.
NEEDS = {"render": (), "detect": ("render",), "estimate": ("render", "detect"),
         "evaluate": ("render", "detect", "estimate"), "pipeline": ()}
WRITES = {
    "render": ("images", "cameras", "frames.parquet", "beacons.parquet", "manifest.json"),
    "detect": ("detections",),
    "estimate": ("estimates",),
    "evaluate": ("evaluation",),
    "pipeline": ("images", "frames.parquet", "beacons.parquet", "detections", "estimates",
                 "evaluation"),
}


#: Keys that name where a run is (each trial's folder differs), not what it found.
WHERE = ("source",)


def _volatile(name: str) -> bool:
    return name in WHERE or any(v in name.lower() for v in VOLATILE)


def _strip(doc: object) -> object:
    if isinstance(doc, dict):
        return {k: _strip(v) for k, v in doc.items() if not _volatile(str(k))}
    if isinstance(doc, list):
        return [_strip(v) for v in doc]
    return doc


def same_file(a: Path, b: Path) -> bool:
    if a.suffix == ".parquet":
        x, y = pd.read_parquet(a), pd.read_parquet(b)
        x = x[[c for c in x.columns if not _volatile(c)]]
        y = y[[c for c in y.columns if not _volatile(c)]]
        try:
            pd.testing.assert_frame_equal(x, y)
        except AssertionError:
            return False
        return True
    if a.suffix == ".json":
        return _strip(json.loads(a.read_text())) == _strip(json.loads(b.read_text()))
    if a.suffix in (".md", ".csv") and a.parent.name == "evaluation":
        # the tables' text has no times; compare as text
        return a.read_text() == b.read_text()
    return a.read_bytes() == b.read_bytes()


def differences(ref: Path, run: Path, stage: str) -> list[str]:
    out = []
    for top in WRITES[stage]:
        r = ref / top
        files = [r] if r.is_file() else sorted(p for p in r.rglob("*") if p.is_file())
        for f in files:
            if f.name.startswith("."):
                continue
            g = run / f.relative_to(ref)
            if not g.exists():
                out.append(f"missing {g.relative_to(run)}")
            elif not same_file(f, g):
                out.append(f"differs {g.relative_to(run)}")
        if r.is_dir():
            extra = [p for p in (run / top).rglob("*") if p.is_file() and not p.name.startswith(".")
                     and not (ref / p.relative_to(run)).exists()]
            out += [f"extra {p.relative_to(run)}" for p in extra]
    return out


def run_cmd(cmd: list[str]) -> tuple[int, float]:
    t0 = time.perf_counter()
    p = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, check=False)
    if p.returncode not in (0,):
        print(f"    rerun failed ({p.returncode}): {p.stderr.strip()[-300:]}")
    return p.returncode, time.perf_counter() - t0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--work", type=Path, default=Path("/tmp/kill_resume"))
    ap.add_argument("--stages", default="render,detect,estimate,evaluate,pipeline")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    shutil.rmtree(args.work, ignore_errors=True)
    args.work.mkdir(parents=True)
    cfg = args.work / "cfg.yaml"
    cfg.write_text(CONFIG)
    ref = args.work / "ref"
    durations = {}
    for stage in ("render", "detect", "estimate", "evaluate"):
        code, durations[stage] = run_cmd(commands(cfg, ref)[stage])
        if code != 0:
            print(f"reference {stage} failed")
            return 1
    pref = args.work / "pipeline_ref"
    code, durations["pipeline"] = run_cmd(commands(cfg, pref)["pipeline"])
    if code != 0:
        print("reference pipeline failed")
        return 1
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"kill_resume: {args.trials} trials per stage, seed {args.seed}; 1-minute load {load:.2f}")
    print("reference durations: " + ", ".join(f"{k} {v:.1f} s" for k, v in durations.items()))
    print(f"{'stage':10s} {'trials':>6s} {'killed':>7s} {'rerun failed':>13s} {'differs':>8s}")
    bad = 0
    for stage in args.stages.split(","):
        killed = failed = differ = 0
        for trial in range(args.trials):
            run = args.work / f"{stage}_{trial}"
            shutil.rmtree(run, ignore_errors=True)
            if NEEDS[stage]:
                shutil.copytree(ref, run, ignore=shutil.ignore_patterns(
                    *[t for s in ("detect", "estimate", "evaluate") if s not in NEEDS[stage]
                      for t in WRITES[s]]))
            cmd = commands(cfg, run)[stage]
            proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                    start_new_session=True)
            time.sleep(float(rng.uniform(0.0, durations[stage])))
            if proc.poll() is None:
                killed += 1
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            code, _ = run_cmd(cmd)
            failed += code != 0
            diffs = differences(pref if stage == "pipeline" else ref, run, stage) if code == 0 else []
            if diffs:
                differ += 1
                print(f"    {stage} trial {trial}: {diffs[:3]}")
            shutil.rmtree(run, ignore_errors=True)
        bad += failed + differ
        print(f"{stage:10s} {args.trials:6d} {killed:7d} {failed:13d} {differ:8d}", flush=True)
    print("all reruns equal the uninterrupted run" if bad == 0 else f"{bad} failed or differing reruns")
    return 0 if bad == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
