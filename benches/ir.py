#!/usr/bin/env python3
"""Two builds of glint compared by instructions executed, not by time:
the same render under valgrind's cachegrind, whose counts do not depend on
how busy the machine is.

    python3 benches/ir.py A B [--mesh PATH] [--size 480x270] [-- ARGS...]

A and B are git revisions or `.` for the working tree, checked out and
built as `benches/ab.py` does (worktrees beside this checkout, removed at
the end). Each side's `glint` renders the mesh (igea from ../shared/data
by default) with one render thread, and cachegrind (`--cache-sim=no`)
counts the instructions of every function; ARGS after `--` are passed to
`glint render` as well (e.g. `-- --integrator whitted`).

The script prints the instructions of three groups of functions (mesh
traversal and leaf tests; loading and building the trees; the rest), each
side's and B's over A's, then the functions whose counts differ most.

What the counts say and what they do not: they are exact and repeatable
(a revision against itself gives the same figures to within the work that
rayon's scheduling of the tree build moves about), so a change of a few
per cent in the traversal's instructions, such as fewer reloads of
constants from the stack, shows at once where wall-clock runs on these
shared machines need many rounds (see ab.py). They do not see memory
latency or branch mispredictions, which dominate traversal on big meshes:
check a gain in instructions with `ab.py` or `vs_tinybvh.py` before
believing it is a gain in time. Valgrind has no AVX-512, so the kernels
counted are the AVX2 ones (the path of CPUs without AVX-512). Installs
Debian's `valgrind` if it is missing (needs root or sudo)."""

import argparse
import os
import re
import shutil
import sys
from collections import defaultdict

from ab import OUT, ROOT, build_artifact, run, source

GROUPS = [
    ("traversal", re.compile(r"bvh8::(traverse|packet)|Bvh8>::(closest|any)|"
                             r"Mesh::(intersect|occludes|leaf)|triangle::")),
    ("load+build", re.compile(r"accel::bvh::build|bvh8::collapse|Bvh8Node::order|"
                              r"meshio|Mesh::new")),
]


def ensure_valgrind():
    if shutil.which("valgrind"):
        return
    sudo = [] if os.geteuid() == 0 else ["sudo"]
    run(sudo + ["apt-get", "update", "-q"])
    run(sudo + ["apt-get", "install", "-y", "-q", "valgrind"])


def build(src, label):
    """Builds glint in `src` and copies the binary to OUT/glint-<label>."""
    return build_artifact(src, ["build", "--release", "--bin", "glint"], "glint", "bin",
                          os.path.join(OUT, "glint-" + label))


def counts(exe, args, label):
    """{function: instructions} of one render under cachegrind."""
    out_file = os.path.join(OUT, f"cachegrind-{label}.out")
    run(["valgrind", "--tool=cachegrind", "--cache-sim=no",
         f"--cachegrind-out-file={out_file}", exe, "render"] + args
        + ["--output", os.path.join(OUT, f"ir-{label}.png"), "-q"], cwd=ROOT)
    per_fn = defaultdict(int)
    name = None
    with open(out_file) as f:
        for line in f:
            if line.startswith("fn="):
                name = line[3:].rstrip("\n")
            elif line[:1].isdigit() and name is not None:
                parts = line.split()
                if len(parts) >= 2:
                    per_fn[name] += int(parts[1])
    return per_fn


def group_of(name):
    for label, pattern in GROUPS:
        if pattern.search(name):
            return label
    return "rest"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("a", help="baseline revision, or . for the working tree")
    parser.add_argument("b", help="revision to compare, or . for the working tree")
    parser.add_argument("--mesh", default=os.path.join(ROOT, "..", "shared", "data",
                                                       "igea_tris.ply"))
    parser.add_argument("--size", default="480x270", help="WxH of the render (480x270)")
    parser.add_argument("--top", type=int, default=12, help="functions listed (12)")
    parser.add_argument("extra", nargs="*", help="more `glint render` arguments, after --")
    args = parser.parse_args()
    args.mesh = os.path.abspath(args.mesh)  # glint runs in the repository root
    if not os.path.exists(args.mesh):
        sys.exit(f"no mesh at {args.mesh} (pass --mesh PATH)")
    width, _, height = args.size.partition("x")
    render = [args.mesh, "--width", width, "--height", height, "--threads", "1"] + args.extra
    ensure_valgrind()
    os.makedirs(OUT, exist_ok=True)
    made = []
    try:
        sides = {}
        for label, rev in (("A", args.a), ("B", args.b)):
            sides[label] = build(source(rev, made), label)
        found = {label: counts(exe, render, label) for label, exe in sides.items()}
    finally:
        for path in made:
            run(["git", "worktree", "remove", "--force", path], cwd=ROOT)
    a, b = found["A"], found["B"]
    print(f"A = {args.a}, B = {args.b}: instructions of `glint render "
          f"{' '.join(render)}`")
    print(f"{'group':<12} {'A':>15} {'B':>15} {'B / A':>7}")
    for g in [label for label, _ in GROUPS] + ["rest", "total"]:
        pick = (lambda n: True) if g == "total" else (lambda n, g=g: group_of(n) == g)
        ia = sum(v for n, v in a.items() if pick(n))
        ib = sum(v for n, v in b.items() if pick(n))
        print(f"{g:<12} {ia:>15,} {ib:>15,} {ib / ia if ia else float('nan'):>7.4f}")
    names = sorted(set(a) | set(b), key=lambda n: -abs(b.get(n, 0) - a.get(n, 0)))
    print("\nfunctions whose counts differ most (B − A):")
    for n in names[:args.top]:
        diff = b.get(n, 0) - a.get(n, 0)
        if diff == 0:
            break
        print(f"{diff:>+15,}  {a.get(n, 0):>13,} → {b.get(n, 0):>13,}  {n[:110]}")


if __name__ == "__main__":
    main()
