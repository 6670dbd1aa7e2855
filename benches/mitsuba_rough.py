#!/usr/bin/env python3
"""The scene of scenes/rough.toml in Mitsuba 3 (`llvm_ad_rgb`), to compare
glint's `path` integrator with at equal time.

Install (as ../shared/anchors/cornell/ says): apt-get install -y libllvm19;
pip install mitsuba==3.9.1 numpy.

    python3 mitsuba_rough.py --ref 4096        # writes ref.exr here
    python3 mitsuba_rough.py --spp 64,256      # times, RMSE against ref.exr
    glint render scenes/rough.toml --time T -o g.exr
    cargo run --release --example rmse g.exr ref.exr

The metals use glint's RGB complex indices (Au, Al) explicitly, and
roughness r as α = r², so both renderers see the same materials."""
import argparse, time, sys
import numpy as np
import mitsuba as mi

AU = ([0.143119, 0.374957, 1.44248], [3.98316, 2.38572, 1.60322])
AL = ([1.65746, 0.880369, 0.521229], [9.22387, 6.26952, 4.837])

def box(lo, hi, bsdf, emit=None):
    lo, hi = np.array(lo, float), np.array(hi, float)
    c, h = (lo + hi) / 2, (hi - lo) / 2
    d = {"type": "cube", "to_world": mi.ScalarTransform4f.translate(c.tolist()) @ mi.ScalarTransform4f.scale(h.tolist()), "bsdf": bsdf}
    if emit: d["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": emit}}
    return d

def scene(size, spp, seed=0):
    white = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.7, 0.7, 0.7]}}
    black = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}}
    def cond(m, r):
        return {"type": "roughconductor", "distribution": "ggx", "alpha": r * r,
                "eta": {"type": "rgb", "value": m[0]}, "k": {"type": "rgb", "value": m[1]}}
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": -1},
        "sensor": {"type": "perspective", "fov": 40, "fov_axis": "y",
                   "to_world": mi.ScalarTransform4f.look_at(origin=[0, 1.5, 6], target=[0, 0.8, 0], up=[0, 1, 0]),
                   "sampler": {"type": "independent", "sample_count": spp, "seed": seed},
                   "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"}, "pixel_format": "rgb"}},
        "floor": box([-3, -0.1, -3], [3, 0, 3], white),
        "wall": box([-3, 0, -3.1], [3, 3, -3], white),
        "lamp": box([-0.8, 3.0, -0.8], [0.8, 3.02, 0.8], black, [12, 12, 12]),
        "gold": {"type": "sphere", "center": [-1.3, 0.6, 0], "radius": 0.6, "bsdf": cond(AU, 0.4)},
        "glass": {"type": "sphere", "center": [0, 0.6, 0.6], "radius": 0.6,
                  "bsdf": {"type": "roughdielectric", "distribution": "ggx", "alpha": 0.09, "int_ior": 1.5, "ext_ior": 1.0}},
        "alu": {"type": "sphere", "center": [1.3, 0.6, 0], "radius": 0.6, "bsdf": cond(AL, 0.2)},
    }

if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--ref", type=int, default=0, help="render a reference of this many spp")
    ap.add_argument("--spp", default="64")
    ap.add_argument("--variant", default="llvm_ad_rgb")
    a = ap.parse_args()
    mi.set_variant(a.variant)
    if a.ref:
        s = mi.load_dict(scene(a.size, a.ref, 12345))
        img = mi.render(s); mi.Bitmap(img).write("ref.exr"); sys.exit(0)
    ref = np.array(mi.Bitmap("ref.exr"))[:, :, :3]
    for spp in [int(x) for x in a.spp.split(",")]:
        s = mi.load_dict(scene(a.size, spp, 1))
        mi.render(s)  # warm-up (JIT)
        t = time.time(); img = mi.render(s, seed=7); dr_sync = np.array(img); t = time.time() - t
        mi.Bitmap(img).write(f"mitsuba_{spp}.exr")
        rmse = float(np.sqrt(np.mean((dr_sync[:, :, :3] - ref) ** 2)))
        print(f"mitsuba {spp} spp: {t:.3f} s, RMSE {rmse:.5f}, mean {dr_sync[:, :, :3].reshape(-1, 3).mean(0)}")
