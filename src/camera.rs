//! Cameras: view and projection transforms into D3D/Vulkan clip space.
//!
//! Conventions: right-handed world and view space, the camera looks down -Z with +Y up;
//! clip space has `-w <= x, y <= w` and `0 <= z <= w` (depth 0 at the near plane), and the
//! viewport maps NDC y = +1 to image row 0. A triangle counter-clockwise in NDC (as seen by the
//! camera) is front-facing.

use glam::{Mat4, Vec3, Vec4};

use crate::error::Error;

/// How the camera projects.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Perspective with a vertical field of view (radians).
    Perspective {
        /// Vertical field of view in radians.
        fov_y: f32,
    },
    /// Orthographic, showing `height` world units vertically.
    Orthographic {
        /// Visible height in world units.
        height: f32,
    },
}

/// A look-at camera with a projection and near/far planes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub eye: Vec3,
    /// Point looked at.
    pub target: Vec3,
    /// Up direction (need not be orthogonal to the view direction).
    pub up: Vec3,
    /// Projection.
    pub projection: Projection,
    /// Near plane distance (> 0).
    pub near: f32,
    /// Far plane distance (> near).
    pub far: f32,
}

/// Default vertical field of view: 35 degrees, a mild "portrait lens" look.
pub const DEFAULT_FOV_Y: f32 = 35.0 * std::f32::consts::PI / 180.0;

impl Camera {
    /// A camera that frames a sphere (`centre`, `radius`) so it fits the image whatever the
    /// aspect ratio, seen from `azimuth` (around +Y, 0 = looking along -Z from +Z) and
    /// `elevation` (radians, positive = from above).
    #[must_use]
    pub fn framing_sphere(
        centre: Vec3,
        radius: f32,
        azimuth: f32,
        elevation: f32,
        aspect: f32,
        projection: Projection,
    ) -> Self {
        let radius = if radius.is_finite() && radius > 0.0 { radius } else { 1.0 };
        let dir = Vec3::new(
            elevation.cos() * azimuth.sin(),
            elevation.sin(),
            elevation.cos() * azimuth.cos(),
        );
        // Distance at which the sphere fits the narrower field of view, with a small margin.
        let margin = 1.08;
        let (distance, projection) = match projection {
            Projection::Perspective { fov_y } => {
                let half_y = fov_y / 2.0;
                let half_x = (half_y.tan() * aspect).atan();
                let half = half_y.min(half_x);
                (margin * radius / half.sin(), projection)
            }
            Projection::Orthographic { .. } => {
                let height = 2.0 * margin * radius * (1.0f32).max(1.0 / aspect);
                (3.0 * radius, Projection::Orthographic { height })
            }
        };
        let up = if dir.y.abs() > 0.999 { Vec3::Z * -dir.y.signum() } else { Vec3::Y };
        Self {
            eye: centre + dir * distance,
            target: centre,
            up,
            projection,
            near: (distance - radius * 1.5).max(distance * 1e-3),
            far: distance + radius * 1.5,
        }
    }

    /// Whether the camera forms an image: its eye, target and up finite, a direction from the
    /// eye to the target and an up not along it (else the view's orientation is arbitrary), a
    /// field of view strictly between 0 and pi (at pi or more the image turns upside down) or
    /// an orthographic height above 0, and near and far planes finite with `near < far`,
    /// `near` above 0 in perspective. A camera that is not (a field of view of 0 or NaN, a
    /// framing of a sphere of radius 3e38, whose eye is infinite) gives non-finite transforms,
    /// under which every triangle is dropped without a word.
    ///
    /// # Errors
    /// [`Error::Camera`] naming the first value that is out of its range.
    pub fn check(&self) -> Result<(), Error> {
        let bad = |what: String| Err(Error::Camera(what));
        for (name, v) in [("eye", self.eye), ("target", self.target), ("up", self.up)] {
            if !v.is_finite() {
                return bad(format!("the {name} {v} is not finite"));
            }
        }
        let Some(view) = direction(self.target - self.eye) else {
            return bad(format!(
                "the eye {} and the target {} are one point (or too far apart to subtract in \
                 single precision): there is no direction to look in",
                self.eye, self.target
            ));
        };
        if direction(view.cross(in_range(self.up))).is_none() {
            return bad(format!(
                "the up {} is zero or along the view direction {view}: the image's roll is \
                 undefined",
                self.up
            ));
        }
        match self.projection {
            Projection::Perspective { fov_y } => {
                if !(fov_y > 0.0 && fov_y < std::f32::consts::PI) {
                    return bad(format!(
                        "the field of view {fov_y} (radians) is not between 0 and pi"
                    ));
                }
                if self.near <= 0.0 {
                    return bad(format!("the near plane {} is not above 0", self.near));
                }
            }
            Projection::Orthographic { height } => {
                if !(height > 0.0 && height.is_finite()) {
                    return bad(format!("the orthographic height {height} is not above 0"));
                }
            }
        }
        if !(self.near.is_finite() && self.far.is_finite()) {
            return bad(format!(
                "the near and far planes {} and {} are not both finite",
                self.near, self.far
            ));
        }
        if self.near >= self.far {
            return bad(format!(
                "the near plane {} is not nearer than the far plane {}",
                self.near, self.far
            ));
        }
        Ok(())
    }

    /// World to view transform. An eye on the target, or an up along the view, gives an
    /// arbitrary orientation ([`Camera::check`] refuses both).
    #[must_use]
    pub fn view(&self) -> Mat4 {
        let f = direction(self.target - self.eye).unwrap_or(Vec3::NEG_Z);
        let s = direction(f.cross(in_range(self.up))).unwrap_or(Vec3::X);
        let u = s.cross(f);
        Mat4::from_cols(
            Vec4::new(s.x, u.x, -f.x, 0.0),
            Vec4::new(s.y, u.y, -f.y, 0.0),
            Vec4::new(s.z, u.z, -f.z, 0.0),
            Vec4::new(-s.dot(self.eye), -u.dot(self.eye), f.dot(self.eye), 1.0),
        )
    }

    /// View to clip transform for an image of the given aspect (width / height).
    #[must_use]
    pub fn projection(&self, aspect: f32) -> Mat4 {
        let (n, f) = (self.near, self.far);
        match self.projection {
            Projection::Perspective { fov_y } => {
                let sy = 1.0 / (fov_y / 2.0).tan();
                let sx = sy / aspect;
                // z_clip = (far * (-z_view) - far * near) / (far - near), w = -z_view.
                let a = f / (n - f);
                Mat4::from_cols(
                    Vec4::new(sx, 0.0, 0.0, 0.0),
                    Vec4::new(0.0, sy, 0.0, 0.0),
                    Vec4::new(0.0, 0.0, a, -1.0),
                    Vec4::new(0.0, 0.0, a * n, 0.0),
                )
            }
            Projection::Orthographic { height } => {
                let sy = 2.0 / height;
                let sx = sy / aspect;
                let a = 1.0 / (n - f);
                Mat4::from_cols(
                    Vec4::new(sx, 0.0, 0.0, 0.0),
                    Vec4::new(0.0, sy, 0.0, 0.0),
                    Vec4::new(0.0, 0.0, a, 0.0),
                    Vec4::new(0.0, 0.0, a * n, 1.0),
                )
            }
        }
    }

    /// World to clip transform.
    #[must_use]
    pub fn view_projection(&self, aspect: f32) -> Mat4 {
        self.projection(aspect) * self.view()
    }
}

/// The unit vector along `v`, or `None` when `v` is zero or not finite. Any other `v` has
/// one: where its squared length underflows or overflows `f32` (components below about
/// 1e-19 or above 1.8e19), `v` is first divided by its largest component. An eye 1e-30
/// above its target had looked along -Z, its direction's length taken as 0.
#[must_use]
pub fn direction(v: Vec3) -> Option<Vec3> {
    in_range(v).try_normalize()
}

/// `v` scaled so that its squared length is a normal `f32`: `v` itself where it is (every
/// camera but the extreme ones keeps its transform's bits) or where it is zero or not finite,
/// else divided by its largest component.
fn in_range(v: Vec3) -> Vec3 {
    let keep = v.length_squared().is_normal() || !v.is_finite() || v == Vec3::ZERO;
    if keep { v } else { v / v.abs().max_element() }
}

/// The smallest sphere-ish bound of a point set: the bounding box's centre and the largest
/// distance from it (within a factor of the optimum, and cheap). Non-finite points are ignored.
/// Each again in `f64` where it overflows in `f32` (the box's `lo + hi` past 1.7e38, the
/// squares of the distances past 1.8e19), where it had been left infinite; in `f32`
/// otherwise, so the framing of every other model is as it was. The radius of points spread
/// past `f32::MAX` is still infinite.
#[must_use]
pub fn bounding_sphere(points: &[[f32; 3]]) -> (Vec3, f32) {
    let finite = points.iter().map(|&p| Vec3::from(p)).filter(|p| p.is_finite());
    let (lo, hi) = finite
        .clone()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(p), hi.max(p)));
    if !lo.is_finite() {
        return (Vec3::ZERO, 1.0);
    }
    let mut centre = (lo + hi) * 0.5;
    if !centre.is_finite() {
        centre = ((lo.as_dvec3() + hi.as_dvec3()) * 0.5).as_vec3();
    }
    let mut radius = finite.clone().map(|p| p.distance(centre)).fold(0.0f32, f32::max);
    if radius == f32::INFINITY {
        let c = centre.as_dvec3();
        radius = finite.map(|p| p.as_dvec3().distance(c)).fold(0.0f64, f64::max) as f32;
    }
    (centre, if radius > 0.0 { radius } else { 1.0 })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Framing cameras form images; a camera with a value out of its range is refused,
    /// naming the value.
    #[test]
    fn cameras_that_form_no_image_are_refused() {
        let perspective = Projection::Perspective { fov_y: DEFAULT_FOV_Y };
        let orthographic = Projection::Orthographic { height: 2.0 };
        for (projection, radius) in [(perspective, 1.0), (orthographic, 1e-30), (perspective, 1e30)]
        {
            // Centred at a point of the sphere's scale: a sphere of 1e-30 about (1, 1, 1) has
            // an eye that `f32` cannot tell from its centre (no view direction, refused).
            let centre = Vec3::ONE * radius;
            let cam = Camera::framing_sphere(centre, radius, 0.5, 0.3, 1.5, projection);
            assert!(cam.check().is_ok(), "{cam:?}");
        }
        let good = Camera::framing_sphere(Vec3::ZERO, 1.0, 0.0, 0.0, 1.0, perspective);
        let with = |f: &dyn Fn(&mut Camera)| {
            let mut cam = good;
            f(&mut cam);
            cam.check().unwrap_err().to_string()
        };
        let fov = |fov_y| move |c: &mut Camera| c.projection = Projection::Perspective { fov_y };
        let height =
            |height| move |c: &mut Camera| c.projection = Projection::Orthographic { height };
        for (err, names) in [
            (with(&|c| c.eye.x = f32::NAN), "eye"),
            (with(&|c| c.target.y = f32::INFINITY), "target"),
            (with(&|c| c.up.z = f32::NEG_INFINITY), "up"),
            (with(&fov(0.0)), "field of view 0"),
            (with(&fov(f32::NAN)), "field of view NaN"),
            (with(&fov(std::f32::consts::PI)), "field of view 3.14"),
            (with(&|c| c.near = 0.0), "near plane 0"),
            (with(&|c| c.near = -1.0), "near plane -1"),
            (with(&|c| c.far = c.near), "not nearer than the far plane"),
            (with(&|c| c.far = f32::INFINITY), "near and far"),
            (with(&height(0.0)), "height 0"),
            (with(&height(f32::INFINITY)), "height inf"),
            (with(&|c| c.eye = c.target), "one point"),
            (with(&|c| c.up = Vec3::ZERO), "up [0, 0, 0] is zero or along"),
            (with(&|c| c.up = c.target - c.eye), "along the view"),
            (with(&|c| (c.eye, c.target) = (Vec3::X * -3e38, Vec3::X * 3e38)), "subtract"),
            // A sphere too large to frame in `f32`: its eye is infinite.
            (
                Camera::framing_sphere(Vec3::ZERO, 3e38, 0.0, 0.0, 1.0, perspective)
                    .check()
                    .unwrap_err()
                    .to_string(),
                "eye",
            ),
        ] {
            assert!(err.starts_with("camera: ") && err.contains(names), "{err}");
        }
        // An orthographic camera may have its near plane behind the eye.
        let mut ortho = good;
        (ortho.projection, ortho.near) = (orthographic, -1.0);
        assert!(ortho.check().is_ok());
    }

    /// The view looks from the eye to the target, with the up direction's roll, whatever the
    /// scale of the two vectors: the same orientation at every scale from 1e-30 to 1e30 (an
    /// eye 1e-30 from its target had looked along -Z).
    #[test]
    fn views_at_every_scale_look_the_same_way() {
        let oriented = |offset: Vec3, up: Vec3| {
            let cam = Camera {
                eye: offset,
                target: Vec3::ZERO,
                up,
                projection: Projection::Perspective { fov_y: 1.0 },
                near: 0.5,
                far: 20.0,
            };
            // The view's rows: right, up and backwards (the eye looks down -Z).
            let v = cam.view();
            (cam.check(), [v.row(0), v.row(1), v.row(2)].map(|r| r.truncate()))
        };
        let (offset, up) = (Vec3::new(0.0, 3.0, 4.0), Vec3::new(1.0, 1.0, 0.0));
        let (ok, want) = oriented(offset, up);
        assert!(ok.is_ok());
        // Backwards is along the offset from the target to the eye.
        assert!(want[2].abs_diff_eq(offset / 5.0, 1e-6), "{want:?}");
        for scale in [1e-30, 1e-20, 1e-10, 1e10, 1e20, 1e30] {
            for (offset, up) in [(offset * scale, up), (offset, up * scale)] {
                let (ok, got) = oriented(offset, up);
                assert!(ok.is_ok(), "{scale}: {ok:?}");
                for (g, w) in got.iter().zip(&want) {
                    assert!(g.abs_diff_eq(*w, 1e-6), "{scale}: {got:?} against {want:?}");
                }
            }
        }
    }

    /// Points near `f32::MAX`, or spread past the square root of it, have a finite sphere
    /// holding them; points spread past `f32::MAX` an infinite radius.
    #[test]
    fn huge_point_sets_have_finite_spheres() {
        for points in [
            vec![[3e38, 0.0, 0.0], [3.4e38, 0.0, 0.0]],
            vec![[1e20, -1e20, 0.0], [-1e20, 1e20, 5.0]],
            vec![[f32::MAX, f32::MAX, f32::MAX], [f32::MAX, f32::MAX, f32::MAX]],
        ] {
            let (centre, radius) = bounding_sphere(&points);
            assert!(centre.is_finite() && radius.is_finite() && radius > 0.0, "{points:?}");
            for p in points {
                let d = Vec3::from(p).as_dvec3().distance(centre.as_dvec3());
                assert!(d <= f64::from(radius) * (1.0 + 1e-6) || radius == 1.0, "{p:?}");
            }
        }
        let (_, radius) = bounding_sphere(&[[-3e38, 0.0, 0.0], [3e38, 1.0, 0.0]]);
        assert!(radius.is_finite());
        let (_, radius) = bounding_sphere(&[[-3e38, -3e38, 0.0], [3e38, 3e38, 0.0]]);
        assert_eq!(radius, f32::INFINITY);
    }

    #[test]
    fn near_maps_to_zero_and_far_to_one() {
        for projection in
            [Projection::Perspective { fov_y: 0.8 }, Projection::Orthographic { height: 2.0 }]
        {
            let cam = Camera {
                eye: Vec3::new(1.0, 2.0, 3.0),
                target: Vec3::new(1.0, 2.0, -7.0),
                up: Vec3::Y,
                projection,
                near: 0.5,
                far: 20.0,
            };
            let m = cam.view_projection(1.5);
            let near = m * Vec4::new(1.0, 2.0, 2.5, 1.0);
            let far = m * Vec4::new(1.0, 2.0, -17.0, 1.0);
            assert!((near.z / near.w).abs() < 1e-6);
            assert!((far.z / far.w - 1.0).abs() < 1e-5);
            // Up in the world is up in NDC.
            let up = m * Vec4::new(1.0, 2.5, -2.0, 1.0);
            assert!(up.y / up.w > 0.0);
            let right = m * Vec4::new(1.5, 2.0, -2.0, 1.0);
            assert!(right.x / right.w > 0.0);
        }
    }
}
