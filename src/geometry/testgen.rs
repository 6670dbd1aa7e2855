//! Generated meshes for tests, benchmarks and examples: closed, consistently
//! wound (counter-clockwise seen from outside), with exactly shared vertices.

use glam::Vec3;
use std::collections::HashMap;

/// An icosahedron subdivided `level` times (20·4^level triangles), vertices
/// projected onto the sphere of radius `radius`.
pub fn icosphere(level: u32, radius: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut v: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, v: &mut Vec<Vec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                v.push(((v[a as usize] + v[b as usize]) * 0.5).normalize());
                v.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(f.len() * 4);
        for [a, b, c] in f {
            let ab = midpoint(a, b, &mut v);
            let bc = midpoint(b, c, &mut v);
            let ca = midpoint(c, a, &mut v);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    (v.into_iter().map(|p| p * radius).collect(), f)
}

/// An icosphere with radial bumps, `r = 1 + 0.08 sin 7x sin 7y sin 7z +
/// 0.02 sin(31x + 17y)` (the bumpy sphere of `shared/anchors/common.py`;
/// level 8 has 1.31M triangles).
pub fn bumpy_icosphere(level: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (v, f) = icosphere(level, 1.0);
    let v = v
        .into_iter()
        .map(|p| {
            let r = 1.0
                + 0.08 * (7.0 * p.x).sin() * (7.0 * p.y).sin() * (7.0 * p.z).sin()
                + 0.02 * (31.0 * p.x + 17.0 * p.y).sin();
            p * r
        })
        .collect();
    (v, f)
}

/// A torus around the z axis with major radius `major` and minor radius
/// `minor`, `nu × nv` quads split into triangles.
pub fn torus(major: f32, minor: f32, nu: u32, nv: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let tau = std::f32::consts::TAU;
    let mut v = Vec::with_capacity((nu * nv) as usize);
    for i in 0..nu {
        let phi = tau * i as f32 / nu as f32;
        for j in 0..nv {
            let theta = tau * j as f32 / nv as f32;
            let r = major + minor * theta.cos();
            v.push(Vec3::new(r * phi.cos(), r * phi.sin(), minor * theta.sin()));
        }
    }
    let id = |i: u32, j: u32| (i % nu) * nv + (j % nv);
    let mut f = Vec::with_capacity((2 * nu * nv) as usize);
    for i in 0..nu {
        for j in 0..nv {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            f.push([a, b, c]);
            f.push([a, c, d]);
        }
    }
    (v, f)
}

/// An `n × n` grid of squares in the plane z = 0 over [0, 1]², two triangles
/// each (open, facing +z).
pub fn grid(n: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut v = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            v.push(Vec3::new(i as f32 / n as f32, j as f32 / n as f32, 0.0));
        }
    }
    let id = |i: u32, j: u32| j * (n + 1) + i;
    let mut f = Vec::new();
    for j in 0..n {
        for i in 0..n {
            f.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            f.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    (v, f)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Closed and consistently wound: every edge appears once in each direction.
    fn assert_closed(f: &[[u32; 3]]) {
        let mut edges = HashMap::new();
        for t in f {
            for k in 0..3 {
                *edges.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        for (&(a, b), &n) in &edges {
            assert_eq!(n, 1, "edge {a}-{b} used {n} times");
            assert_eq!(edges.get(&(b, a)), Some(&1), "edge {a}-{b} has no twin");
        }
    }

    #[test]
    fn generated_meshes_are_closed_and_outward() {
        let (v, f) = icosphere(3, 2.0);
        assert_eq!(f.len(), 20 * 64);
        assert_closed(&f);
        for t in &f {
            let (a, b, c) = (v[t[0] as usize], v[t[1] as usize], v[t[2] as usize]);
            assert!((b - a).cross(c - a).dot(a + b + c) > 0.0, "inward triangle");
        }
        let (_, f) = torus(1.0, 0.3, 24, 12);
        assert_closed(&f);
    }
}
