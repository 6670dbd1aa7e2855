#!/usr/bin/env python3
"""Two builds of glint timed in turns on one criterion bench: is B faster
than A, by more than the machine's noise?

    python3 benches/ab.py A B [--bench bvh] [--filter REGEX] [--rounds 4]

A and B are git revisions (`HEAD~1`, a commit, a branch) or `.` for the
working tree as it is. Each revision other than `.` is checked out with
`git worktree` next to this checkout (`../glint-ab-<commit>`, so that
paths such as `../shared/data` resolve as they do here; removed at the
end) and its bench built with `cargo bench --no-run` into this
checkout's target folder (the dependencies are built once; glint itself
is rebuilt for each side). Then the two
bench binaries run in rounds, A first in odd rounds and B first in even
ones, each with its own criterion folder (`CRITERION_HOME`), so that
neither compares against the other's saved samples and a machine getting
slower or faster during the run favours neither.

For every benchmark id the script prints the median over rounds of each
side's time (each run's figure: the median of criterion's per-iteration
samples, as `vs_tinybvh.py` takes it), B's speed relative to A's (A's time
over B's: above 1 when B is faster) and the range of the rounds' ratios.
A difference is worth believing only where that range stays on one side
of 1 over several rounds: on the shared 2-core machines, two binaries
doing the same work have timed up to 27 % apart in a single pair of runs.

Comparing a revision with itself (`ab.py HEAD HEAD`) shows that noise
floor for the chosen benches. Run it alone on the machine."""

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

from criterion_samples import median_ns

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
OUT = os.environ.get("OUT", "/tmp/glint_ab")


def run(cmd, **kw):
    """`cmd`'s output; on failure, its error output and an exit."""
    print("+", " ".join(cmd), file=sys.stderr)
    done = subprocess.run(cmd, text=True, capture_output=True, **kw)
    if done.returncode != 0:
        sys.stderr.write(done.stderr[-4000:])
        raise SystemExit(f"failed ({done.returncode}): {' '.join(cmd)}")
    return done.stdout


def source(rev, made):
    """The folder holding revision `rev` (`.`: this checkout as it is); a
    worktree the script adds is listed in `made`."""
    if rev == ".":
        return ROOT
    commit = run(["git", "rev-parse", "--verify", rev + "^{commit}"], cwd=ROOT).strip()
    path = os.path.join(os.path.dirname(ROOT), "glint-ab-" + commit[:12])
    if not os.path.isdir(path):
        run(["git", "worktree", "add", "--detach", path, commit], cwd=ROOT)
        made.append(path)
    return path


def build_artifact(src, cargo_args, name, kind, dest):
    """Runs `cargo CARGO_ARGS` in `src` and copies the executable of target
    `name` (of kind `kind`: "bench" or "bin") to `dest`. glint's own
    artifacts are cleaned first: both sides build into one target folder
    (the dependencies are built once), and cargo names glint's artifacts
    the same for any checkout of the workspace, so without the clean a
    side whose files are older than the other side's build is taken as
    up to date and gets the other side's binary."""
    target = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
    env = dict(os.environ, CARGO_TARGET_DIR=target)
    run(["cargo", "clean", "--release", "-p", "glint"], cwd=src, env=env)
    out = run(["cargo"] + cargo_args + ["--message-format=json"], cwd=src, env=env)
    exe = None
    for line in out.splitlines():
        try:
            msg = json.loads(line)
        except ValueError:
            continue
        if (msg.get("reason") == "compiler-artifact" and msg.get("executable")
                and msg["target"]["name"] == name and kind in msg["target"]["kind"]):
            exe = msg["executable"]
    if exe is None:
        sys.exit(f"cargo built no {kind} executable named {name} in {src}")
    run(["cp", exe, dest])
    return dest


def build(src, bench, label):
    """Builds `bench` in `src` and copies its binary to OUT/<label>."""
    return build_artifact(src, ["bench", "--bench", bench, "--no-run"], bench, "bench",
                          os.path.join(OUT, label))


def timings(home, since):
    """{benchmark id: median ns per iteration} of the runs written under
    criterion folder `home` after time `since`."""
    found = {}
    for folder, _, files in os.walk(home):
        if os.path.basename(folder) != "new" or "sample.json" not in files:
            continue
        if os.path.getmtime(os.path.join(folder, "sample.json")) < since:
            continue
        try:
            with open(os.path.join(folder, "benchmark.json")) as f:
                name = json.load(f)["full_id"]
        except (OSError, KeyError, ValueError):
            continue
        ns = median_ns(folder)
        if ns is not None:
            found[name] = ns
    return found


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("a", help="baseline revision, or . for the working tree")
    parser.add_argument("b", help="revision to compare, or . for the working tree")
    parser.add_argument("--bench", default="bvh", help="bench target (bvh)")
    parser.add_argument("--filter", default="",
                        help="criterion filter (a regex on benchmark ids), e.g. "
                             "'bvh/(primary|shadow)/igea'")
    parser.add_argument("--rounds", type=int, default=4, help="rounds of both (4)")
    args = parser.parse_args()
    if args.rounds < 1:
        parser.error("--rounds must be at least 1")
    os.makedirs(OUT, exist_ok=True)
    made = []
    try:
        compare(args, made)
    finally:
        for path in made:
            run(["git", "worktree", "remove", "--force", path], cwd=ROOT)


def compare(args, made):
    sides = []
    for label, rev in (("A", args.a), ("B", args.b)):
        src = source(rev, made)
        sides.append((label, rev, src, build(src, args.bench, label)))
    results = {"A": [], "B": []}
    for r in range(args.rounds):
        for label, _, src, exe in (sides if r % 2 == 0 else sides[::-1]):
            home = os.path.join(OUT, "criterion-" + label)
            since = time.time()
            cmd = [exe, "--bench", "--noplot"] + ([args.filter] if args.filter else [])
            run(cmd, cwd=src, env=dict(os.environ, CRITERION_HOME=home))
            results[label].append(timings(home, since))
        line = "; ".join(f"{n} {results['A'][-1][n] / results['B'][-1][n]:.3f}"
                         for n in sorted(results["A"][-1]) if n in results["B"][-1])
        print(f"round {r + 1}, B's speed / A's: {line}", flush=True)
    names = sorted(set().union(*results["A"]) & set().union(*results["B"]))
    if not names:
        sys.exit("no benchmark ran on both sides (check --filter)")
    width = max(len(n) for n in names)
    print(f"\nA = {args.a}, B = {args.b}; medians over {args.rounds} rounds, "
          "time per iteration")
    print(f"{'benchmark':<{width}} {'A':>11} {'B':>11} {'B speed':>8}  rounds")
    for n in names:
        pairs = [(a[n], b[n]) for a, b in zip(results["A"], results["B"]) if n in a and n in b]
        ta = statistics.median(p[0] for p in pairs)
        tb = statistics.median(p[1] for p in pairs)
        each = [a / b for a, b in pairs]
        print(f"{n:<{width}} {ta / 1e6:9.3f}ms {tb / 1e6:9.3f}ms {ta / tb:8.3f}  "
              f"{min(each):.3f}-{max(each):.3f}")


if __name__ == "__main__":
    main()
