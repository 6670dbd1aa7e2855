#!/usr/bin/env python3
"""glint's mesh kernels against tinybvh's BVH8_CPU, side by side, on the same
meshes and rays, and the ratios.

tinybvh is built from ../shared/anchors/tinybvh (its header, bench.cpp and
README: g++ with OpenMP, `-O3 -march=native`); the bumpy icosphere comes
from ../shared/anchors/common.py (needs numpy and trimesh). Both sides trace
1920x1080 primary rays through pixel centres and the shadow rays of the lit
hits, on both cores, as ../shared/anchors/embree_bench.py defines them; the
figure compared is tinybvh's `BVH8_CPU 2 thr` line and the middle of
criterion's throughput for glint's `bvh/primary/MESH` and `bvh/shadow/MESH`.

    python3 benches/vs_tinybvh.py                 # igea and icosphere_8
    python3 benches/vs_tinybvh.py other.ply ...   # any binary PLY meshes too

Run it alone on the machine: the two are timed one after the other, and
ratios from a machine busy with other work mean little."""

import os
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SHARED = os.path.join(ROOT, "..", "shared")
ANCHORS = os.path.join(SHARED, "anchors")
OUT = os.environ.get("OUT", "/tmp/vs_tinybvh")


def run(cmd, **kw):
    print("+", " ".join(cmd), file=sys.stderr)
    return subprocess.run(cmd, check=True, text=True, capture_output=True, **kw).stdout


def tinybvh(mesh):
    """(primary, shadow) Mrays/s of BVH8_CPU on 2 threads."""
    out = run([os.path.join(OUT, "bench_native"), mesh, "--runs", "5", "--no-hq"])
    for line in out.splitlines():
        m = re.match(r"\s*BVH8_CPU\s+2 thr: primary\s+([\d.]+) Mrays/s.*shadow \d+ rays\s+([\d.]+) Mrays/s", line)
        if m:
            return float(m.group(1)), float(m.group(2))
    sys.exit(f"no BVH8_CPU 2-thread line in tinybvh's output for {mesh}:\n{out}")


def glint(meshes):
    """{name: (primary, shadow)} Mrays/s from glint's bvh bench."""
    names = [os.path.splitext(os.path.basename(m))[0] for m in meshes]
    env = dict(os.environ, GLINT_BENCH_MESHES=":".join(meshes))
    pattern = "(primary|shadow)/(" + "|".join(map(re.escape, names)) + ")$"
    out = run(["cargo", "bench", "--bench", "bvh", "--", pattern], cwd=ROOT, env=env)
    found = {}
    current = None
    for line in out.splitlines():
        m = re.match(r"bvh/(primary|shadow)/(\S+)", line)
        if m:
            current = (m.group(1), m.group(2))
        m = re.search(r"thrpt:\s+\[\S+ \S+ ([\d.]+) (K|M|G)elem/s", line)
        if m and current and "%" not in line:
            scale = {"K": 1e-3, "M": 1.0, "G": 1e3}[m.group(2)]
            found[current] = float(m.group(1)) * scale
            current = None
    return {n: (found.get(("primary", n)), found.get(("shadow", n))) for n in names}


def main():
    tb = os.path.join(ANCHORS, "tinybvh")
    if not os.path.isfile(os.path.join(tb, "tiny_bvh.h")):
        sys.exit(f"{tb}/tiny_bvh.h is not there: this script needs ../shared/anchors/tinybvh")
    os.makedirs(OUT, exist_ok=True)
    run(["g++", "-O3", "-march=native", "-fopenmp", "-std=c++20", "-I" + tb,
         os.path.join(tb, "bench.cpp"), "-o", os.path.join(OUT, "bench_native"), "-lpthread"])
    meshes = sys.argv[1:]
    if not meshes:
        sys.path.insert(0, ANCHORS)
        import common  # noqa: E402  (numpy, trimesh)
        meshes = [os.path.join(SHARED, "data", "igea_tris.ply")]
        meshes += common.generated_meshes([8], os.path.join(OUT, "meshes"))
    meshes = [os.path.abspath(m) for m in meshes]
    ours = glint(meshes)
    print(f"{'mesh':<16} {'kind':<8} {'glint':>8} {'tinybvh':>8} {'ratio':>6}   (Mrays/s, 2 threads)")
    for mesh in meshes:
        name = os.path.splitext(os.path.basename(mesh))[0]
        theirs = tinybvh(mesh)
        for k, kind in enumerate(["primary", "shadow"]):
            g, t = ours[name][k], theirs[k]
            ratio = f"{g / t:6.2f}" if g else "   n/a"
            print(f"{name:<16} {kind:<8} {g or float('nan'):8.2f} {t:8.2f} {ratio}")


if __name__ == "__main__":
    main()
