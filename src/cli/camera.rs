//! The pinhole camera of `bvhc render`, and its primary rays.

use bvhc::loader::Ray;
use glam::Vec3;

/// A pinhole camera: where it is, what it looks at, and its vertical field of view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub target: Vec3,
    pub fov_degrees: f32,
}

impl Camera {
    /// The ray through the centre of pixel `(x, y)` of a `width` x `height` image.
    pub fn primary_ray(&self, x: usize, y: usize, width: usize, height: usize) -> Ray {
        let forward = (self.target - self.eye).normalize_or(Vec3::Z);
        let mut right = forward.cross(Vec3::Y).normalize_or(Vec3::Z);
        if right.length_squared() < 0.5 || forward.cross(Vec3::Y) == Vec3::ZERO {
            right = forward.cross(Vec3::Z).normalize_or(Vec3::Z); // looking straight up or down
        }
        let up = right.cross(forward);
        let half_height = (0.5 * self.fov_degrees).to_radians().tan();
        let half_width = half_height * width as f32 / height as f32;
        let sx = (2.0 * (x as f32 + 0.5) / width as f32 - 1.0) * half_width;
        let sy = (1.0 - 2.0 * (y as f32 + 0.5) / height as f32) * half_height;
        let direction = (forward + sx * right + sy * up).normalize_or(Vec3::Z);
        Ray::new(self.eye.to_array(), direction.to_array())
    }
}
