#!/usr/bin/env python3
"""glint's mesh kernels against tinybvh's BVH8_CPU, side by side, on the same
meshes and rays, and the ratios.

tinybvh is built from ../shared/anchors/tinybvh (its header, bench.cpp and
README: g++ with OpenMP, `-O3 -march=native`); the bumpy icosphere comes
from ../shared/anchors/common.py (needs numpy and trimesh). Both sides trace
1920x1080 primary rays through pixel centres and the shadow rays of the lit
hits, on both cores, as ../shared/anchors/embree_bench.py defines them; the
figure compared is tinybvh's `BVH8_CPU 2 thr` line and the middle of
criterion's throughput for glint's `bvh/primary/MESH` and `bvh/shadow/MESH`;
then glint's packets of 16 rays (`bvh/primary_packets/MESH`,
`bvh/shadow_packets/MESH`: the same rays in 4x4 pixel blocks) against the
same BVH8_CPU lines, and glint's primary packets against the faster of
tinybvh's two 256-ray packet kernels (`BVH 256-pkt`, primary rays only).

    python3 benches/vs_tinybvh.py                 # igea and icosphere_8
    python3 benches/vs_tinybvh.py other.ply ...   # other meshes (ASCII PLY
                                                  # and OBJ are converted)

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
    """(primary, shadow, best packet primary) Mrays/s of BVH8_CPU and of
    tinybvh's fastest 256-ray packet kernel, on 2 threads."""
    out = run([os.path.join(OUT, "bench_native"), mesh, "--runs", "5", "--no-hq"])
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


def glint(meshes):
    """{name: (primary, shadow)} Mrays/s from glint's bvh bench."""
    names = [os.path.splitext(os.path.basename(m))[0] for m in meshes]
    env = dict(os.environ, GLINT_BENCH_MESHES=":".join(meshes))
    pattern = "(primary|shadow|primary_packets|shadow_packets)/(" + "|".join(map(re.escape, names)) + ")$"
    out = run(["cargo", "bench", "--bench", "bvh", "--", pattern], cwd=ROOT, env=env)
    found = {}
    current = None
    for line in out.splitlines():
        m = re.match(r"bvh/(primary|shadow|primary_packets|shadow_packets)/(\S+)", line)
        if m:
            current = (m.group(1), m.group(2))
        m = re.search(r"thrpt:\s+\[\S+ \S+ ([\d.]+) (K|M|G)elem/s", line)
        if m and current and "%" not in line:
            scale = {"K": 1e-3, "M": 1.0, "G": 1e3}[m.group(2)]
            found[current] = float(m.group(1)) * scale
            current = None
    kinds = ["primary", "shadow", "primary_packets", "shadow_packets"]
    return {n: tuple(found.get((k, n)) for k in kinds) for n in names}


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
    meshes = [binary_ply(os.path.abspath(m)) for m in meshes]
    ours = glint(meshes)
    print(f"{'mesh':<16} {'kind':<8} {'glint':>8} {'tinybvh':>8} {'ratio':>6}   (Mrays/s, 2 threads)")
    for mesh in meshes:
        name = os.path.splitext(os.path.basename(mesh))[0]
        theirs = tinybvh(mesh)
        # glint's single rays and packets against BVH8_CPU's single rays,
        # and glint's primary packets against tinybvh's best packet kernel.
        rows = [("primary", 0, 0), ("shadow", 1, 1), ("primary_packets", 2, 0),
                ("shadow_packets", 3, 1), ("primary_packets", 2, 2)]
        for kind, ko, kt in rows:
            g, t = ours[name][ko], theirs[kt]
            label = kind if kt != 2 else kind + " vs tinybvh's packets"
            ratio = f"{g / t:6.2f}" if g and t else "   n/a"
            print(f"{name:<16} {label:<8} {g or float('nan'):8.2f} {t or float('nan'):8.2f} {ratio}")


if __name__ == "__main__":
    main()
