//! Axis-aligned bounding boxes.

use super::{Real, Vec3};

/// An axis-aligned box `[min, max]`; the empty box has `min > max`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vec3,
    /// Upper corner.
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The empty box: the identity of [`Aabb::union`].
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::new(Real::INFINITY, Real::INFINITY, Real::INFINITY),
        max: Vec3::new(Real::NEG_INFINITY, Real::NEG_INFINITY, Real::NEG_INFINITY),
    };

    /// The smallest box containing all `points`.
    #[inline]
    pub fn from_points<'a>(points: impl IntoIterator<Item = &'a Vec3>) -> Aabb {
        let mut b = Aabb::EMPTY;
        for p in points {
            b.grow(p);
        }
        b
    }

    /// Enlarges the box to contain `p`.
    #[inline]
    pub fn grow(&mut self, p: &Vec3) {
        self.min = self.min.inf(p);
        self.max = self.max.sup(p);
    }

    /// The smallest box containing both boxes.
    #[inline]
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb {
            min: self.min.inf(&o.min),
            max: self.max.sup(&o.max),
        }
    }

    /// The box grown by `d` on every side.
    #[inline]
    pub fn inflated(&self, d: Real) -> Aabb {
        let v = Vec3::new(d, d, d);
        Aabb {
            min: self.min - v,
            max: self.max + v,
        }
    }

    /// Whether the closed boxes share at least one point.
    #[inline]
    pub fn overlaps(&self, o: &Aabb) -> bool {
        self.min.x <= o.max.x
            && o.min.x <= self.max.x
            && self.min.y <= o.max.y
            && o.min.y <= self.max.y
            && self.min.z <= o.max.z
            && o.min.z <= self.max.z
    }

    /// Whether the box contains no point.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    /// Centre of the box.
    #[inline]
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Edge lengths of the box.
    #[inline]
    pub fn extent(&self) -> Vec3 {
        self.max - self.min
    }

    /// Half the surface area (the SAH cost measure).
    #[inline]
    pub fn half_area(&self) -> Real {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.extent();
        e.x * e.y + e.y * e.z + e.z * e.x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overlap_is_closed_and_symmetric() {
        let a = Aabb::from_points(&[Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 1.0)]);
        let b = Aabb::from_points(&[Vec3::new(1.0, 1.0, 1.0), Vec3::new(2.0, 2.0, 2.0)]);
        let c = Aabb::from_points(&[Vec3::new(1.5, 0.0, 0.0), Vec3::new(2.0, 1.0, 1.0)]);
        assert!(a.overlaps(&b) && b.overlaps(&a));
        assert!(!a.overlaps(&c) && !c.overlaps(&a));
        assert!(Aabb::EMPTY.is_empty());
        assert!(!Aabb::EMPTY.overlaps(&a));
        assert_eq!(a.union(&Aabb::EMPTY), a);
    }
}
