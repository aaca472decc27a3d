"""Ctrl-C a multi-worker ``deckpose render`` or ``pipeline`` many times: does it always stop cleanly?

Each trial starts the command (``--workers 2``) in its own process group, waits a random
moment (uniform over the first ``--window`` of the uninterrupted run's duration, so the
interrupt lands in the render stage, the detect stage or while the workers start), and
sends SIGINT to the whole group, as a terminal's Ctrl-C does. Counted per command:

* ``hung``: still running ``--timeout`` seconds after the interrupt (then killed);
* ``slow``: exited, but more than ``--stop-within`` seconds after it;
* ``bad exit``: an exit status other than 130 (interrupted) or 0 (finished before it);
* ``traceback``: stderr holds a Python traceback (a worker's or the parent's);
* ``rerun failed``: the same command (render: with ``--resume``) did not then finish with 0,
  or left a temporary file behind.

Printed: those counts, and the median and largest seconds from the interrupt to the exit.

Usage::

    .venv/bin/python benchmarks/ctrl_c_workers.py [--trials 10] [--seed 0] [--work /tmp/ctrl_c_workers]

Another checkout (laid out as installed: deckpose/ holding render/, detect/, estimate/, evaluate/)::

    PYTHONPATH=CHECKOUT:.venv/lib/python3.11/site-packages .venv/bin/python -S benchmarks/ctrl_c_workers.py
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

CONFIG = """\
name: ctrlc
seed: 4
cameras: [{preset: 4mp, size: [640, 480]}]
heights_m: [30, 40]
lighting: [dusk]
motion: {source: fixed, attitudes_deg: [[0, 0, 0], [2, 1, 5], [-2, 3, 10], [4, -1, 20], [1, 1, 30], [-3, -2, 40]]}
scene: {texture_px: 128}
"""

#: With ``python -S`` (and the checkout and site-packages on PYTHONPATH) the commands run a
#: checkout other than the installed one, e.g. an older commit to compare with.
DECKPOSE = [sys.executable, *(["-S"] if sys.flags.no_site else []), "-m", "deckpose"]


def command(kind: str, cfg: Path, run: Path, *, rerun: bool = False) -> list[str]:
    if kind == "render":
        return [*DECKPOSE, "render", str(cfg), str(run), "--workers", "2", "--no-progress",
                *(["--resume"] if rerun else [])]
    return [*DECKPOSE, "pipeline", str(cfg), str(run), "--workers", "2", "--method", "pnp", "--no-mcap",
            "--no-progress"]


def temp_files(run: Path) -> list[Path]:
    from deckpose.atomic_io import is_temp_name

    return [p for p in run.rglob("*") if p.is_file() and is_temp_name(p.name)]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--trials", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--work", type=Path, default=Path("/tmp/ctrl_c_workers"))
    ap.add_argument("--commands", default="render,pipeline")
    ap.add_argument("--window", type=float, default=0.8, help="fraction of the run's duration to interrupt in")
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds after the interrupt that count as hung")
    ap.add_argument("--stop-within", type=float, default=5.0, help="seconds after the interrupt that count as slow")
    args = ap.parse_args()
    # A job started in the background of a shell (``... &``, nohup) begins with SIGINT ignored, and an
    # ignored signal stays ignored through exec: the commands would never see the interrupt. Handled
    # here, it is reset to the default in them.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    rng = np.random.default_rng(args.seed)
    shutil.rmtree(args.work, ignore_errors=True)
    args.work.mkdir(parents=True)
    cfg = args.work / "cfg.yaml"
    cfg.write_text(CONFIG)
    print(f"ctrl_c_workers: {args.trials} trials per command, seed {args.seed}; "
          f"1-minute load {os.getloadavg()[0]:.2f}, {os.cpu_count()} cores", flush=True)
    bad = 0
    for kind in args.commands.split(","):
        ref = args.work / f"{kind}_ref"
        t0 = time.perf_counter()
        done = subprocess.run(command(kind, cfg, ref), capture_output=True, text=True, check=False)
        duration = time.perf_counter() - t0
        if done.returncode != 0:
            print(f"the uninterrupted {kind} failed ({done.returncode}): {done.stderr[-400:]}")
            return 1
        hung = slow = bad_exit = traceback = rerun_failed = interrupted = 0
        stops: list[float] = []
        for trial in range(args.trials):
            run = args.work / f"{kind}_{trial}"
            shutil.rmtree(run, ignore_errors=True)
            proc = subprocess.Popen(command(kind, cfg, run), stdout=subprocess.DEVNULL,
                                    stderr=subprocess.PIPE, text=True, start_new_session=True)
            time.sleep(float(rng.uniform(0.0, args.window * duration)))
            t_int = time.perf_counter()
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGINT)
                interrupted += 1
            try:
                _, err = proc.communicate(timeout=args.timeout)
                stops.append(time.perf_counter() - t_int)
            except subprocess.TimeoutExpired:
                hung += 1
                os.killpg(proc.pid, signal.SIGKILL)
                _, err = proc.communicate()
                print(f"    {kind} trial {trial}: hung; stderr {err.strip()[-300:]!r}")
            slow += bool(stops) and stops[-1] > args.stop_within
            if proc.returncode not in (0, 130, -signal.SIGKILL):
                bad_exit += 1
                print(f"    {kind} trial {trial}: exit {proc.returncode}; stderr {err.strip()[-300:]!r}")
            if "Traceback" in err:
                traceback += 1
                print(f"    {kind} trial {trial}: traceback: {err.strip()[-400:]!r}")
            again = subprocess.run(command(kind, cfg, run, rerun=True), capture_output=True, text=True,
                                   check=False)
            left = temp_files(run)
            if again.returncode != 0 or left:
                rerun_failed += 1
                print(f"    {kind} trial {trial}: rerun {again.returncode}, temporary files {left[:3]}; "
                      f"{again.stderr.strip()[-300:]!r}")
            shutil.rmtree(run, ignore_errors=True)
        bad += hung + slow + bad_exit + traceback + rerun_failed
        med = float(np.median(stops)) if stops else float("nan")
        print(f"{kind}: uninterrupted {duration:.1f} s; {args.trials} trials, {interrupted} interrupted; "
              f"hung {hung}, slow {slow}, bad exit {bad_exit}, traceback {traceback}, rerun failed "
              f"{rerun_failed}; interrupt to exit median {med:.2f} s, max {max(stops, default=float('nan')):.2f} s; "
              f"load {os.getloadavg()[0]:.2f}", flush=True)
    print("every interrupt stopped cleanly" if bad == 0 else f"{bad} problems")
    return 0 if bad == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
