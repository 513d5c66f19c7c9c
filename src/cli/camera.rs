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

/// Parses `--camera ex,ey,ez,tx,ty,tz`: six finite numbers, the eye and the target different points (a usage
/// error otherwise, reported by clap before any file is read).
pub fn parse_camera(text: &str) -> Result<Camera, String> {
    let expected = || "expected six numbers ex,ey,ez,tx,ty,tz".to_string();
    let values: Vec<f32> =
        text.split(',').map(|v| v.trim().parse::<f32>()).collect::<Result<_, _>>().map_err(|_| expected())?;
    let [ex, ey, ez, tx, ty, tz] = values[..] else { return Err(expected()) };
    if !values.iter().all(|v| v.is_finite()) || [ex, ey, ez] == [tx, ty, tz] {
        return Err("the eye and the target must be finite and different points".to_string());
    }
    Ok(Camera { eye: Vec3::new(ex, ey, ez), target: Vec3::new(tx, ty, tz), fov_degrees: 45.0 })
}
