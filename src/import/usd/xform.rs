//! `UsdGeomXformable`'s local transform, composed from a prim's `xformOpOrder` as USD's own
//! `UsdGeomXformable::GetLocalTransformation` composes it, in f64: the first op listed is the outermost, the
//! last the first applied to a point; `!invert!` inverts an op; a leading `!resetXformStack!` drops the parent's
//! transform. Matrices here are glam's (column vectors), so USD's row-vector product `p * op_n * ... * op_1`
//! is `op_1 * ... * op_n * p`. An op of a kind USD does not define, or a value of the wrong type, is refused by
//! name rather than read as the identity.

use glam::{DMat4, DQuat, DVec3};
use openusd::sdf::Value;
use openusd::usd::{Prim, TimeCode};

/// A prim's local transform at a time (`None`: the default time, which reads authored defaults only, as
/// `UsdTimeCode::Default()` does) and whether it resets the transform stack.
pub(super) struct LocalTransform {
    pub matrix: DMat4,
    pub resets_stack: bool,
}

/// The local transform of `prim` at `time`; the identity when it lists no ops. Errors name the op.
pub(super) fn local_transform(prim: &Prim, time: Option<TimeCode>) -> Result<LocalTransform, String> {
    let order = match prim.attribute("xformOpOrder").get::<Value>().map_err(|e| format!("xformOpOrder: {e}"))? {
        None => return Ok(LocalTransform { matrix: DMat4::IDENTITY, resets_stack: false }),
        Some(Value::TokenVec(tokens)) => tokens.iter().map(|t| t.as_str().to_string()).collect::<Vec<_>>(),
        Some(Value::StringVec(names)) => names,
        Some(other) => return Err(format!("xformOpOrder is not a token array ({})", value_kind(&other))),
    };
    let mut matrix = DMat4::IDENTITY;
    let mut resets_stack = false;
    for (position, name) in order.iter().enumerate() {
        if name == "!resetXformStack!" {
            if position != 0 {
                return Err(format!("xformOpOrder: !resetXformStack! at position {position}, only allowed first"));
            }
            resets_stack = true;
            continue;
        }
        matrix *= op_matrix(prim, name, time).map_err(|e| format!("{name}: {e}"))?;
    }
    if !matrix.is_finite() {
        return Err("xformOpOrder composes a transform that is not finite".to_string());
    }
    Ok(LocalTransform { matrix, resets_stack })
}

/// The world transform of the prim at `path` at `time`: its ancestors' local transforms composed from the root,
/// restarted where one resets the transform stack.
pub(super) fn world_transform(
    stage: &openusd::usd::Stage,
    path: &openusd::sdf::Path,
    time: Option<TimeCode>,
) -> Result<DMat4, String> {
    let mut chain = Vec::new();
    let mut at = Some(path.clone());
    while let Some(prim_path) = at {
        if prim_path.as_str() == "/" {
            break;
        }
        at = prim_path.parent();
        chain.push(prim_path);
    }
    let mut world = DMat4::IDENTITY;
    for prim_path in chain.iter().rev() {
        let local = local_transform(&stage.prim(prim_path.clone()), time)
            .map_err(|e| format!("{}: {e}", prim_path.as_str()))?;
        world = if local.resets_stack { local.matrix } else { world * local.matrix };
    }
    Ok(world)
}

/// The matrix of one op, inverted for `!invert!`; the identity when the op's attribute holds no value at `time`
/// (as USD reads it).
fn op_matrix(prim: &Prim, name: &str, time: Option<TimeCode>) -> Result<DMat4, String> {
    let (inverted, attribute) = match name.strip_prefix("!invert!") {
        Some(rest) => (true, rest),
        None => (false, name),
    };
    let Some(kind) = attribute.strip_prefix("xformOp:").map(|rest| rest.split(':').next().unwrap_or(rest)) else {
        return Err("not an xformOp attribute".to_string());
    };
    let Some(value) = prim.attribute(attribute).get_at::<Value>(time).map_err(|e| e.to_string())? else {
        return Ok(DMat4::IDENTITY);
    };
    let degrees =
        |axis: DVec3| -> Result<DMat4, String> { Ok(DMat4::from_axis_angle(axis, scalar(&value)?.to_radians())) };
    let matrix = match kind {
        "translate" => DMat4::from_translation(vector(&value)?),
        "translateX" => DMat4::from_translation(DVec3::X * scalar(&value)?),
        "translateY" => DMat4::from_translation(DVec3::Y * scalar(&value)?),
        "translateZ" => DMat4::from_translation(DVec3::Z * scalar(&value)?),
        "scale" => DMat4::from_scale(vector(&value)?),
        "scaleX" => DMat4::from_scale(DVec3::new(scalar(&value)?, 1.0, 1.0)),
        "scaleY" => DMat4::from_scale(DVec3::new(1.0, scalar(&value)?, 1.0)),
        "scaleZ" => DMat4::from_scale(DVec3::new(1.0, 1.0, scalar(&value)?)),
        "rotateX" => degrees(DVec3::X)?,
        "rotateY" => degrees(DVec3::Y)?,
        "rotateZ" => degrees(DVec3::Z)?,
        "rotateXYZ" | "rotateXZY" | "rotateYXZ" | "rotateYZX" | "rotateZXY" | "rotateZYX" => {
            let angles = vector(&value)?;
            // rotateABC turns about A first, then B, then C: C * B * A on column vectors.
            kind[6..].chars().fold(DMat4::IDENTITY, |m, axis| {
                let (unit, angle) = match axis {
                    'X' => (DVec3::X, angles.x),
                    'Y' => (DVec3::Y, angles.y),
                    _ => (DVec3::Z, angles.z),
                };
                DMat4::from_axis_angle(unit, angle.to_radians()) * m
            })
        }
        "orient" => DMat4::from_quat(quaternion(&value)?),
        "transform" => match value {
            // USD stores rows for row vectors: as glam's columns, the same numbers are the transpose.
            Value::Matrix4d(m) => DMat4::from_cols_array(&m.0),
            other => return Err(format!("a transform op holds {}, not a matrix4d", value_kind(&other))),
        },
        other => return Err(format!("'{other}' is not an op kind USD defines")),
    };
    if !inverted {
        return Ok(matrix);
    }
    if matrix.determinant() == 0.0 {
        return Err("!invert! of a singular matrix".to_string());
    }
    Ok(matrix.inverse())
}

/// A scalar op value (float, double, half).
fn scalar(value: &Value) -> Result<f64, String> {
    match value {
        Value::Double(v) => Ok(*v),
        Value::Float(v) => Ok(f64::from(*v)),
        Value::Half(v) => Ok(f64::from(v.to_f32())),
        other => Err(format!("holds {}, not a scalar", value_kind(other))),
    }
}

/// A 3-vector op value (double3, float3, half3).
pub(super) fn vector(value: &Value) -> Result<DVec3, String> {
    match value {
        Value::Vec3d(v) => Ok(DVec3::new(v.x, v.y, v.z)),
        Value::Vec3f(v) => Ok(DVec3::new(f64::from(v.x), f64::from(v.y), f64::from(v.z))),
        Value::Vec3h(v) => Ok(DVec3::new(f64::from(v.x.to_f32()), f64::from(v.y.to_f32()), f64::from(v.z.to_f32()))),
        other => Err(format!("holds {}, not a 3-vector", value_kind(other))),
    }
}

/// A quaternion op value (quatd, quatf, quath), normalized as USD's rotation from it is.
fn quaternion(value: &Value) -> Result<DQuat, String> {
    let (w, x, y, z) = match value {
        Value::Quatd(q) => (q.w, q.x, q.y, q.z),
        Value::Quatf(q) => (f64::from(q.w), f64::from(q.x), f64::from(q.y), f64::from(q.z)),
        Value::Quath(q) => {
            (f64::from(q.w.to_f32()), f64::from(q.x.to_f32()), f64::from(q.y.to_f32()), f64::from(q.z.to_f32()))
        }
        other => return Err(format!("holds {}, not a quaternion", value_kind(other))),
    };
    quaternion_of(w, x, y, z)
}

/// The rotation of an authored quaternion (real part first), normalized; a zero quaternion is refused.
fn quaternion_of(w: f64, x: f64, y: f64, z: f64) -> Result<DQuat, String> {
    let q = DQuat::from_xyzw(x, y, z, w);
    let length = q.length();
    if !(length.is_finite() && length > 0.0) {
        return Err(format!("the quaternion ({w}, {x}, {y}, {z}) names no rotation"));
    }
    Ok(q / length)
}

/// A value's type, for messages.
pub(super) fn value_kind(value: &Value) -> String {
    let text = format!("{value:?}");
    text.split(['(', ' ', '{']).next().unwrap_or("a value").to_string()
}
