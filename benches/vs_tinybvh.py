#!/usr/bin/env python3
"""glint's mesh kernels against tinybvh's BVH8_CPU, side by side, on the same
meshes and rays, and the ratios.

tinybvh is built from ../shared/anchors/tinybvh (its header, bench.cpp and
README: g++ with OpenMP, `-O3 -march=native`); the bumpy icosphere comes
from ../shared/anchors/common.py (needs numpy and trimesh). Both sides trace
1920x1080 primary rays through pixel centres and the shadow rays of the lit
hits, on both cores, as ../shared/anchors/embree_bench.py defines them.

Both figures are medians of repeated timings: tinybvh's `BVH8_CPU 2 thr`
line is the median of its 5 runs, and glint's is the median of criterion's
samples (per-iteration times in `target/criterion/bvh/KIND/MESH/new/
sample.json`) for `bvh/primary/MESH` and `bvh/shadow/MESH`. Criterion's own
printed estimate is a regression slope, which one slow sample on a busy
machine pulls down; the median is the statistic tinybvh reports.

The two are run in rounds (`--rounds N`, 3 by default), glint first in odd
rounds and tinybvh first in even ones, so that a machine getting slower or
faster during the run does not favour either side. Each round prints its
ratios; the summary gives, per mesh and kind, the medians over rounds of
both figures, their ratio, and the range of the rounds' ratios. Then
glint's packets of 16 rays (`bvh/primary_packets/MESH`,
`bvh/shadow_packets/MESH`: the same rays in 4x4 pixel blocks, traced as
the renderer traces them, one by one where packets would lose) against the
same BVH8_CPU figures, and glint's primary packets against the faster of
tinybvh's two 256-ray packet kernels (`BVH 256-pkt`, primary rays only).

    python3 benches/vs_tinybvh.py                 # igea and icosphere_8
    python3 benches/vs_tinybvh.py other.ply ...   # other meshes (ASCII PLY
                                                  # and OBJ are converted)
    python3 benches/vs_tinybvh.py --rounds 5 ...

Run it alone on the machine: the two are timed one after the other, and
ratios from a machine busy with other work mean little."""

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys

from criterion_samples import median_ns

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SHARED = os.path.join(ROOT, "..", "shared")
ANCHORS = os.path.join(SHARED, "anchors")
OUT = os.environ.get("OUT", "/tmp/vs_tinybvh")


def run(cmd, **kw):
    print("+", " ".join(cmd), file=sys.stderr)
    return subprocess.run(cmd, check=True, text=True, capture_output=True, **kw).stdout


def tinybvh(mesh):
    """(primary, shadow, best packet primary) Mrays/s of BVH8_CPU and of
    tinybvh's fastest 256-ray packet kernel, on 2 threads."""
    # Above 10M triangles, tinybvh's bench builds only the layouts it then
    # traces (`--big`: no reference build, no SoA, CWBVH or packet layouts),
    # as run.sh runs it for the 25.6M-triangle mesh: its other builders
    # would take many minutes a round.
    big = ["--big"] if ply_faces(mesh) > 10_000_000 else []
    out = run([os.path.join(OUT, "bench_native"), mesh, "--runs", "5", "--no-hq"] + big)
    single, packets = None, []
    for line in out.splitlines():
        m = re.match(r"\s*BVH8_CPU\s+2 thr: primary\s+([\d.]+) Mrays/s.*shadow \d+ rays\s+([\d.]+) Mrays/s", line)
        if m:
            single = float(m.group(1)), float(m.group(2))
        m = re.match(r"\s*BVH 256-pkt.*2 thr: primary\s+([\d.]+) Mrays/s", line)
        if m:
            packets.append(float(m.group(1)))
    if single is None:
        sys.exit(f"no BVH8_CPU 2-thread line in tinybvh's output for {mesh}:\n{out}")
    return single + (max(packets) if packets else None,)


KINDS = ["primary", "shadow", "primary_packets", "shadow_packets"]


def glint(meshes):
    """{name: (primary, shadow, primary_packets, shadow_packets)} Mrays/s
    from glint's bvh bench: rays over the median of criterion's samples."""
    names = [os.path.splitext(os.path.basename(m))[0] for m in meshes]
    env = dict(os.environ, GLINT_BENCH_MESHES=":".join(meshes))
    pattern = "(" + "|".join(KINDS) + ")/(" + "|".join(map(re.escape, names)) + ")$"
    run(["cargo", "bench", "--bench", "bvh", "--", pattern], cwd=ROOT, env=env)
    target = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))

    def figure(kind, name):
        d = os.path.join(target, "criterion", "bvh", kind, name, "new")
        try:
            with open(os.path.join(d, "benchmark.json")) as f:
                rays = json.load(f)["throughput"]["Elements"]
        except (OSError, KeyError, ValueError):
            return None
        ns = median_ns(d)
        return None if ns is None else rays / ns * 1e3  # ns -> Mrays/s

    return {n: tuple(figure(k, n) for k in KINDS) for n in names}


def patched_copy(tb):
    """A folder with copies of tinybvh's bench.cpp and header, in which
    BVH8_CPU's buffer size is computed in 64 bits: tinybvh 1.6.7 multiplies
    a uint32 count of 64-byte blocks, which wraps above 4 GiB (about 20M
    triangles), and `ConvertFrom` then writes past the buffer (the fix
    run.sh applies for BIG=1). Below 4 GiB the product is the same, so
    smaller meshes get the very same code. (bench.cpp is copied too: it
    includes the header by a quoted name, found beside it first.)"""
    with open(os.path.join(tb, "tiny_bvh.h")) as f:
        text = f.read()
    wrapped = "allocator( blocksNeeded * 64, 0 )"
    if wrapped not in text:
        print("+ tiny_bvh.h has no uint32 buffer size to fix; used as it is", file=sys.stderr)
    folder = os.path.join(OUT, "tinybvh_src")
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, "tiny_bvh.h"), "w") as f:
        f.write(text.replace(wrapped, "allocator( (size_t)blocksNeeded * 64, 0 )"))
    shutil.copyfile(os.path.join(tb, "bench.cpp"), os.path.join(folder, "bench.cpp"))
    return folder


def ply_faces(mesh):
    """The face count in a binary PLY's header (0 if it has none)."""
    with open(mesh, "rb") as f:
        for line in f:
            words = line.split()
            if words[:2] == [b"element", b"face"]:
                return int(words[2])
            if words[:1] == [b"end_header"]:
                break
    return 0


# The Python packages this script uses, at the versions
# ../shared/anchors/README.md measured with; installed from PyPI when missing.
PACKAGES = {"numpy": "numpy==2.4.6", "trimesh": "trimesh==5.2.0"}


def ensure_packages():
    """Installs the missing ones of `PACKAGES` (the bumpy icosphere and the
    conversion of ASCII PLY and OBJ need them), with pip for this Python."""
    import importlib.util
    missing = [spec for name, spec in PACKAGES.items() if importlib.util.find_spec(name) is None]
    if missing:
        run([sys.executable, "-m", "pip", "install", "--quiet"] + missing)


def binary_ply(mesh):
    """`mesh` itself if it is a binary little-endian PLY, which tinybvh's
    bench.cpp reads; otherwise (an ASCII PLY such as the Stanford bunny,
    an OBJ, ...) a copy converted by trimesh, unprocessed, into OUT/meshes
    under the same name, which both sides then read."""
    with open(mesh, "rb") as f:
        head = f.read(512)
    if head.startswith(b"ply") and b"format binary_little_endian" in head:
        return mesh
    import trimesh  # noqa: E402
    out = os.path.join(OUT, "meshes", os.path.splitext(os.path.basename(mesh))[0] + ".ply")
    os.makedirs(os.path.dirname(out), exist_ok=True)
    m = trimesh.load(mesh, process=False, force="mesh")
    with open(out, "wb") as f:
        f.write(trimesh.exchange.ply.export_ply(m, encoding="binary"))
    print(f"+ {mesh} converted to binary PLY: {out}", file=sys.stderr)
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("meshes", nargs="*", help="PLY or OBJ files (default: igea, icosphere_8)")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds of both (3)")
    args = parser.parse_args()
    if args.rounds < 1:
        parser.error("--rounds must be at least 1")
    tb = os.path.join(ANCHORS, "tinybvh")
    if not os.path.isfile(os.path.join(tb, "tiny_bvh.h")):
        sys.exit(f"{tb}/tiny_bvh.h is not there: this script needs ../shared/anchors/tinybvh")
    os.makedirs(OUT, exist_ok=True)
    ensure_packages()
    src = patched_copy(tb)
    run(["g++", "-O3", "-march=native", "-fopenmp", "-std=c++20", "-I" + src,
         os.path.join(src, "bench.cpp"), "-o", os.path.join(OUT, "bench_native"), "-lpthread"])
    meshes = args.meshes
    if not meshes:
        sys.path.insert(0, ANCHORS)
        import common  # noqa: E402  (numpy, trimesh)
        meshes = [os.path.join(SHARED, "data", "igea_tris.ply")]
        meshes += common.generated_meshes([8], os.path.join(OUT, "meshes"))
    meshes = [binary_ply(os.path.abspath(m)) for m in meshes]
    names = [os.path.splitext(os.path.basename(m))[0] for m in meshes]
    # (glint row index, tinybvh row index, label) of each comparison.
    rows = [(0, 0, "primary"), (1, 1, "shadow"), (2, 0, "primary_packets"),
            (3, 1, "shadow_packets"), (2, 2, "primary_packets vs tinybvh's packets")]
    ours, theirs = [], []
    for r in range(args.rounds):
        both = [lambda: ours.append(glint(meshes)),
                lambda: theirs.append({n: tinybvh(m) for n, m in zip(names, meshes)})]
        for step in (both if r % 2 == 0 else both[::-1]):
            step()
        print(f"round {r + 1}: " + "; ".join(
            f"{n} {label} {ours[-1][n][g] / theirs[-1][n][t]:.2f}"
            for n in names for g, t, label in rows[:2]
            if ours[-1][n][g] and theirs[-1][n][t]), flush=True)
    print(f"\n{'mesh':<16} {'kind':<38} {'glint':>8} {'tinybvh':>8} {'ratio':>6}  rounds"
          f"   (Mrays/s, 2 threads, medians over {args.rounds} rounds)")
    for n in names:
        for g, t, label in rows:
            gs = [o[n][g] for o in ours if o[n][g]]
            ts = [x[n][t] for x in theirs if x[n][t]]
            if not gs or not ts:
                print(f"{n:<16} {label:<38} {'n/a':>8}")
                continue
            gm, tm = statistics.median(gs), statistics.median(ts)
            each = [o[n][g] / x[n][t] for o, x in zip(ours, theirs) if o[n][g] and x[n][t]]
            print(f"{n:<16} {label:<38} {gm:8.2f} {tm:8.2f} {gm / tm:6.2f}  "
                  f"{min(each):.2f}-{max(each):.2f}")


if __name__ == "__main__":
    main()
