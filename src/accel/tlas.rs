//! The top level: an acceleration structure over a scene's objects, seen
//! only as boxes. Objects with finite boxes go into a [`Bvh`]; objects with
//! infinite ones (planes) cannot be bounded and are kept in a list that
//! every ray tests first. Objects with empty boxes (merged into another
//! structure by the scene, say) are in neither.

use super::{Bvh, TraversalCounters};
use crate::math::{Aabb, Ray};

/// A BVH over the objects with finite boxes, and the list of the others.
#[derive(Clone, Debug, Default)]
pub struct Tlas {
    bvh: Bvh,
    /// Objects with infinite boxes, tested by every ray, in order.
    unbounded: Vec<u32>,
}

impl Tlas {
    /// Builds over the objects' boxes (object `i` has `bounds[i]`).
    pub fn build(bounds: &[Aabb]) -> Tlas {
        // Infinite but not empty (an empty box runs from +∞ to −∞).
        let unbounded = (0..bounds.len() as u32)
            .filter(|&i| {
                let b = &bounds[i as usize];
                !(b.min.is_finite() && b.max.is_finite()) && b.min.cmple(b.max).all()
            })
            .collect();
        // The BVH's builder leaves infinite and empty boxes out.
        Tlas {
            bvh: Bvh::build(bounds),
            unbounded,
        }
    }

    /// The BVH over the bounded objects.
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// Closest hit: `test(object, t_max)` is called for the unbounded
    /// objects in order, then for the bounded ones whose boxes the ray meets
    /// before the closest hit so far, front to back; it returns the hit's
    /// `t` (below `t_max`) or `None`. Starts from `ray.t_max`.
    #[inline]
    pub fn closest(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        mut test: impl FnMut(u32, f32) -> Option<f32>,
    ) {
        let mut t_max = ray.t_max;
        for &i in &self.unbounded {
            if let Some(t) = test(i, t_max) {
                t_max = t;
            }
        }
        let ray = Ray { t_max, ..*ray };
        self.bvh.closest(&ray, counters, test);
    }

    /// Any hit: `test(object)` for the unbounded objects, then the bounded
    /// ones whose boxes meet the ray's segment, until one returns true;
    /// returns whether one did.
    #[inline]
    pub fn any(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        mut test: impl FnMut(u32) -> bool,
    ) -> bool {
        self.unbounded.iter().any(|&i| test(i)) || self.bvh.any(ray, counters, test)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    #[test]
    fn unbounded_objects_come_first_then_boxes_front_to_back() {
        let unit = |x: f32| Aabb::new(Vec3::new(x, -1.0, -1.0), Vec3::new(x + 1.0, 1.0, 1.0));
        let bounds = [
            unit(5.0),
            Aabb::new(Vec3::NEG_INFINITY, Vec3::INFINITY),
            Aabb::EMPTY,
            unit(2.0),
        ];
        let tlas = Tlas::build(&bounds);
        let ray = Ray::new(Vec3::new(0.0, 0.0, 0.0), Vec3::X);
        let mut seen = Vec::new();
        let mut counters = TraversalCounters::default();
        let mut closest = None;
        // Each object "hits" at its box's near side; the plane never does.
        tlas.closest(&ray, &mut counters, |i, t_max| {
            seen.push(i);
            let t = bounds[i as usize].min.x;
            let hit = (i != 1 && t < t_max).then_some(t);
            if hit.is_some() {
                closest = Some(i);
            }
            hit
        });
        // The plane first, the empty box never; box 3 is the closest.
        assert_eq!(seen[0], 1);
        assert!(seen.contains(&3) && !seen.contains(&2));
        assert_eq!(closest, Some(3));
        // A ray that starts past both boxes meets only the plane.
        let mut seen = Vec::new();
        let past = Ray::new(Vec3::new(7.0, 0.0, 0.0), Vec3::X);
        tlas.closest(&past, &mut counters, |i, _| {
            seen.push(i);
            None
        });
        assert_eq!(seen, vec![1]);
        let mut seen = Vec::new();
        assert!(tlas.any(&ray, &mut counters, |i| {
            seen.push(i);
            i == 0
        }));
        assert!(seen.contains(&0) && seen[0] == 1 && !seen.contains(&2));
    }
}
