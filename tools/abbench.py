#!/usr/bin/env python3
"""Compare builds of trirast on one benchmark scene, runs alternated.

    python3 tools/abbench.py SCENE LABEL=BINARY[:VAR=VALUE,...] ... [--rounds 6]
        [--frames 20] [--threads 2]

Each round runs `BINARY bench SCENE --json` once per build, in the order given, so that
every build sees the same minutes of a machine whose speed drifts (on the 2-vCPU VM the
same binary's soup has taken 49 ms in one minute and 70 ms in the next). A build may set
environment variables for its runs (`scalar=target/release/trirast:TRIRAST_SIMD=scalar`).

For each build it prints the fastest frame of all its runs, the median over runs of each
run's fastest frame (the figure to compare: a frame's floor moves less with the neighbours
than its median does) and the median over runs of each run's median frame.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys


def build(spec):
    """LABEL=BINARY[:VAR=VALUE,...] -> (label, binary, environment)."""
    label, sep, rest = spec.partition("=")
    if not sep or not rest:
        raise argparse.ArgumentTypeError(f"expected LABEL=BINARY[:VAR=VALUE,...], got {spec!r}")
    binary, _, assignments = rest.partition(":")
    env = dict(os.environ)
    for assignment in filter(None, assignments.split(",")):
        name, sep, value = assignment.partition("=")
        if not sep:
            raise argparse.ArgumentTypeError(f"expected VAR=VALUE, got {assignment!r}")
        env[name] = value
    return label, binary, env


def run(binary, env, scene, frames, threads):
    """One `trirast bench` run: its (fastest, median) frame in ms."""
    command = [binary, "bench", scene, "--frames", str(frames), "--threads", str(threads),
               "--json"]
    try:
        done = subprocess.run(command, capture_output=True, text=True, env=env)
    except OSError as e:
        sys.exit(f"cannot run {binary}: {e.strerror}")
    if done.returncode != 0:
        sys.exit(f"{' '.join(command)} failed ({done.returncode}):\n{done.stderr}")
    result = json.loads(done.stdout.strip().splitlines()[-1])
    return result["min_ms"], result["median_ms"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", help="bunny, soup, grid, fill or dense")
    parser.add_argument("builds", nargs="+", type=build, metavar="LABEL=BINARY[:VAR=VALUE,...]")
    parser.add_argument("--rounds", type=int, default=6)
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    if args.rounds < 1 or args.frames < 1 or args.threads < 1:
        parser.error("--rounds, --frames and --threads take 1 or more")
    labels = [label for label, _, _ in args.builds]
    if len(set(labels)) < len(labels):
        parser.error(f"each build needs a label of its own, got {', '.join(labels)}")

    runs = {label: [] for label, _, _ in args.builds}
    for _ in range(args.rounds):
        for label, binary, env in args.builds:
            runs[label].append(run(binary, env, args.scene, args.frames, args.threads))

    width = max(len(label) for label in ["build", *runs])
    print(f"{args.scene}, {args.rounds} alternated runs of {args.frames} frames each, "
          f"{args.threads} threads (ms)")
    print(f"{'build':{width}}  fastest  median of fastest  median of medians")
    for label, results in runs.items():
        fastest = [f for f, _ in results]
        medians = [m for _, m in results]
        print(f"{label:{width}}  {min(fastest):7.2f}  {statistics.median(fastest):17.2f}"
              f"  {statistics.median(medians):17.2f}")


if __name__ == "__main__":
    main()
