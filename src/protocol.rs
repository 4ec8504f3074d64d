//! Protocol v1 between the MARVIN side (vision, `marvin run`, `marvin calibrate`) and the robot
//! server (`marvin serve`), as `docs/PROTOCOL.md` describes it: TCP, one JSON object per line.
//!
//! The types here are the protocol: the server parses requests into them and writes replies
//! from them, the client ([`crate::engine::client`]) writes requests from them and parses replies into
//! them, so the two cannot drift. Everything a peer sends is checked here ([`parse_request`],
//! [`WirePose::to_isometry`]) before anything acts on it.

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};
use std::collections::BTreeMap;

/// The protocol's version, which `hello` states.
pub const PROTOCOL: u32 = 1;
/// Longest request line, bytes (its newline not counted).
pub const MAX_LINE_BYTES: usize = 1 << 20;
/// Connections served at once; one more is told `busy` and closed.
pub const MAX_CONNECTIONS: usize = 8;
/// A connection that sends nothing for this long is closed, seconds.
pub const IDLE_TIMEOUT_S: f64 = 30.0;
/// A rotation must be a unit quaternion to within this.
pub const UNIT_QUATERNION_TOLERANCE: f64 = 1e-3;
/// Poses farther than this from their frame's origin are refused, metres: the cell is a metre
/// or two across, and a number this large is a mistake.
pub const MAX_TRANSLATION_M: f64 = 100.0;

/// What went wrong, as the `code` of an error reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ErrorCode {
    /// The line is not a JSON object (or not UTF-8).
    BadJson,
    /// The line is longer than [`MAX_LINE_BYTES`]; the connection is closed.
    TooLarge,
    UnknownOp,
    /// A field missing, of the wrong type, not finite, out of range, or a rotation that is not a
    /// unit quaternion.
    BadRequest,
    /// No or a wrong token; the connection is closed.
    Unauthorized,
    UnknownModel,
    UnknownBin,
    /// Inverse kinematics found no solution; the message says why.
    Unreachable,
    /// Solutions exist but no collision-free path reaches them.
    NoPath,
    /// Another motion is running, or the server has no room for another connection.
    Busy,
    /// A `cam`-frame pose before any hand-eye transform is known.
    NotCalibrated,
    Internal,
}

impl ErrorCode {
    pub fn as_str(self) -> &'static str {
        match self {
            ErrorCode::BadJson => "bad_json",
            ErrorCode::TooLarge => "too_large",
            ErrorCode::UnknownOp => "unknown_op",
            ErrorCode::BadRequest => "bad_request",
            ErrorCode::Unauthorized => "unauthorized",
            ErrorCode::UnknownModel => "unknown_model",
            ErrorCode::UnknownBin => "unknown_bin",
            ErrorCode::Unreachable => "unreachable",
            ErrorCode::NoPath => "no_path",
            ErrorCode::Busy => "busy",
            ErrorCode::NotCalibrated => "not_calibrated",
            ErrorCode::Internal => "internal",
        }
    }
}

/// An error reply's `error`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[error("{}: {message}", code.as_str())]
pub struct WireError {
    pub code: ErrorCode,
    pub message: String,
}

impl WireError {
    pub fn new(code: ErrorCode, message: impl Into<String>) -> WireError {
        WireError { code, message: message.into() }
    }
}

/// The frames a pose on the wire may be given in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Frame {
    /// The robot's base.
    Base,
    /// The left camera.
    Cam,
    /// The gripper's tool centre point.
    Gripper,
}

/// A pose: where a thing is, in `frame` (absent where the field's name says it, as in
/// `cam_from_base`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WirePose {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame: Option<Frame>,
    pub translation_m: [f64; 3],
    pub rotation_xyzw: [f64; 4],
}

impl WirePose {
    pub fn new(frame: Option<Frame>, iso: &Isometry3<f64>) -> WirePose {
        let q = iso.rotation.coords;
        let t = iso.translation.vector;
        WirePose { frame, translation_m: [t.x, t.y, t.z], rotation_xyzw: [q.x, q.y, q.z, q.w] }
    }

    /// The pose as an isometry, if its numbers are finite, its translation within
    /// [`MAX_TRANSLATION_M`] and its rotation a unit quaternion within
    /// [`UNIT_QUATERNION_TOLERANCE`]; `field` names it in the error.
    pub fn to_isometry(&self, field: &str) -> Result<Isometry3<f64>, WireError> {
        let bad = |m: String| WireError::new(ErrorCode::BadRequest, format!("`{field}`: {m}"));
        let [x, y, z] = self.translation_m;
        if ![x, y, z].iter().all(|v| v.is_finite()) {
            return Err(bad(format!("translation_m {:?} is not finite", self.translation_m)));
        }
        let t = Translation3::new(x, y, z);
        if t.vector.norm() > MAX_TRANSLATION_M {
            return Err(bad(format!("translation_m {:?} is over {MAX_TRANSLATION_M} m away", self.translation_m)));
        }
        let [qx, qy, qz, qw] = self.rotation_xyzw;
        if ![qx, qy, qz, qw].iter().all(|v| v.is_finite()) {
            return Err(bad(format!("rotation_xyzw {:?} is not finite", self.rotation_xyzw)));
        }
        let q = Quaternion::new(qw, qx, qy, qz);
        if (q.norm() - 1.0).abs() > UNIT_QUATERNION_TOLERANCE {
            return Err(bad(format!(
                "rotation_xyzw {:?} has norm {:.6}, not 1 within {UNIT_QUATERNION_TOLERANCE}",
                self.rotation_xyzw,
                q.norm()
            )));
        }
        Ok(Isometry3::from_parts(t, UnitQuaternion::from_quaternion(q)))
    }

    /// As [`WirePose::to_isometry`], and the frame must be one of `allowed`.
    pub fn in_frames(&self, field: &str, allowed: &[Frame]) -> Result<(Frame, Isometry3<f64>), WireError> {
        let iso = self.to_isometry(field)?;
        match self.frame {
            Some(f) if allowed.contains(&f) => Ok((f, iso)),
            other => Err(WireError::new(
                ErrorCode::BadRequest,
                format!("`{field}.frame` must be one of {allowed:?} (lower case), got {other:?}"),
            )),
        }
    }
}

/// Where `move` takes the arm: a tool pose in `base`, or joint positions by URDF name (those
/// not named stay where they are).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MoveTarget {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tool: Option<WirePose>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joints: Option<BTreeMap<String, f64>>,
    /// Fraction of the joints' speed limits, in (0, 1] (default 0.8): calibration moves slowly
    /// so that a held tool does not creep in the jaws.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed: Option<f64>,
}

/// A grasp: the gripper's pose (`cam` or `base`) and the jaw opening the object needs there.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WireGrasp {
    pub frame: Option<Frame>,
    pub translation_m: [f64; 3],
    pub rotation_xyzw: [f64; 4],
    pub jaw_mm: f64,
}

impl WireGrasp {
    pub fn new(pose: WirePose, jaw_mm: f64) -> WireGrasp {
        WireGrasp { frame: pose.frame, translation_m: pose.translation_m, rotation_xyzw: pose.rotation_xyzw, jaw_mm }
    }

    pub fn pose(&self) -> WirePose {
        WirePose { frame: self.frame, translation_m: self.translation_m, rotation_xyzw: self.rotation_xyzw }
    }
}

/// Where a picked object goes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlaceSpec {
    /// A bin's name, as `hello` lists them.
    pub bin: String,
}

/// Another object's pose, for the planner to keep clear of.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WireObject {
    pub model: String,
    pub pose: WirePose,
}

/// `pick`: which model, where to grasp it, where to put it; optionally the object's own pose
/// (then every grasp of the model is open to the planner, the one given first) and the other
/// objects seen (obstacles). Poses in `cam` need the hand-eye transform.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PickSpec {
    pub model: String,
    pub grasp: WireGrasp,
    pub place: PlaceSpec,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub object: Option<WirePose>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub obstacles: Vec<WireObject>,
    /// Plan only (inverse kinematics and paths), reply with `plan_ms`, and do not move.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub plan_only: bool,
}

/// A request, by its `op`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "op", rename_all = "snake_case", deny_unknown_fields)]
pub enum Request {
    Hello {
        protocol: u32,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        token: Option<String>,
    },
    Status {},
    Capture {},
    Move(MoveTarget),
    SetHandEye {
        cam_from_base: WirePose,
    },
    Pick(PickSpec),
    /// The operator hands a tool (the calibration flag) into the gripper, which closes on it.
    TakeTool {
        tool: String,
    },
    /// The gripper opens and the operator takes the tool away.
    StowTool {},
    Home {},
    Shutdown {},
    Bye {},
    /// Evaluation only, on a server started with `--truth`: the simulation's ground truth.
    Truth {},
}

/// Every op, as requests name them.
pub const OPS: [&str; 12] = [
    "hello",
    "status",
    "capture",
    "move",
    "set_hand_eye",
    "pick",
    "take_tool",
    "stow_tool",
    "home",
    "shutdown",
    "bye",
    "truth",
];

impl Request {
    pub fn op(&self) -> &'static str {
        match self {
            Request::Hello { .. } => "hello",
            Request::Status {} => "status",
            Request::Capture {} => "capture",
            Request::Move(_) => "move",
            Request::SetHandEye { .. } => "set_hand_eye",
            Request::Pick(_) => "pick",
            Request::TakeTool { .. } => "take_tool",
            Request::StowTool {} => "stow_tool",
            Request::Home {} => "home",
            Request::Shutdown {} => "shutdown",
            Request::Bye {} => "bye",
            Request::Truth {} => "truth",
        }
    }

    /// Whether the op moves the arm (one such at a time).
    pub fn is_motion(&self) -> bool {
        matches!(
            self,
            Request::Move(_) | Request::Pick(_) | Request::Home {} | Request::TakeTool { .. } | Request::StowTool {}
        )
    }
}

/// A request line taken apart: its `id` (echoed in the reply, `null` if absent) and the
/// request, or why it is not one.
pub fn parse_request(line: &[u8]) -> (Value, Result<Request, WireError>) {
    let text = match std::str::from_utf8(line) {
        Ok(t) => t,
        Err(e) => return (Value::Null, Err(WireError::new(ErrorCode::BadJson, format!("not UTF-8: {e}")))),
    };
    let mut map: Map<String, Value> = match serde_json::from_str::<Value>(text) {
        Ok(Value::Object(m)) => m,
        Ok(other) => {
            let kind = match other {
                Value::Array(_) => "an array",
                Value::String(_) => "a string",
                Value::Number(_) => "a number",
                Value::Bool(_) => "a boolean",
                _ => "null",
            };
            return (
                Value::Null,
                Err(WireError::new(ErrorCode::BadJson, format!("a request is a JSON object, not {kind}"))),
            );
        }
        Err(e) => return (Value::Null, Err(WireError::new(ErrorCode::BadJson, format!("not JSON: {e}")))),
    };
    let id = map.remove("id").unwrap_or(Value::Null);
    let op = match map.get("op") {
        Some(Value::String(op)) => op.clone(),
        Some(other) => {
            return (id, Err(WireError::new(ErrorCode::BadRequest, format!("`op` must be a string, got {other}"))));
        }
        None => return (id, Err(WireError::new(ErrorCode::BadRequest, "missing field `op`"))),
    };
    if !OPS.contains(&op.as_str()) {
        let shown: String = op.chars().take(64).collect();
        return (
            id,
            Err(WireError::new(ErrorCode::UnknownOp, format!("unknown op `{shown}`; known: {}", OPS.join(", ")))),
        );
    }
    let request = serde_json::from_value::<Request>(Value::Object(map))
        .map_err(|e| WireError::new(ErrorCode::BadRequest, format!("`{op}`: {e}")));
    (id, request)
}

/// A reply line: `{"id":..,"ok":true, ...body}` or `{"id":..,"ok":false,"error":{..}}`.
pub fn reply_line(id: &Value, result: &Result<Value, WireError>) -> String {
    let mut map = Map::new();
    map.insert("id".into(), id.clone());
    match result {
        Ok(body) => {
            map.insert("ok".into(), Value::Bool(true));
            if let Value::Object(fields) = body {
                map.extend(fields.iter().map(|(k, v)| (k.clone(), v.clone())));
            }
        }
        Err(e) => {
            map.insert("ok".into(), Value::Bool(false));
            map.insert("error".into(), serde_json::to_value(e).expect("an error serialises"));
        }
    }
    Value::Object(map).to_string()
}

/// `hello`'s reply.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HelloReply {
    pub server: String,
    pub protocol: u32,
    pub models: Vec<String>,
    pub bins: Vec<String>,
    /// Where the bins are: the cell's layout, which a client needs to tell parts on the table
    /// from parts already placed.
    pub bin_boxes: Vec<BinBox>,
    /// The table's top, its height in `base`, metres: the cell's layout too, so a client can
    /// tell a part resting on the table from a reading of one in mid-air.
    #[serde(default)]
    pub table_top_base_m: Option<f64>,
    pub calibrated: bool,
}

/// A bin's inside, as a box aligned with the base frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BinBox {
    pub name: String,
    pub centre_base_m: [f64; 3],
    pub size_m: [f64; 3],
}

/// `status`'s reply.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StatusReply {
    /// Joint positions by URDF name (metres for the prismatic zed, radians for the rest).
    pub joints: BTreeMap<String, f64>,
    pub gripper_opening_mm: f64,
    /// The model the gripper holds, if the server knows it holds one.
    pub holding: Option<String>,
    pub calibrated: bool,
    pub sim_time_s: f64,
    /// Whether a motion is running (the joints are then those from before it).
    pub moving: bool,
}

/// A camera's intrinsics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// The lens's `plumb_bob` distortion `[k1, k2, p1, p2, k3]`, when the cameras were measured
    /// (`marvin serve --cameras`); absent for none.
    #[serde(default, skip_serializing_if = "no_distortion")]
    pub distortion: [f64; 5],
}

fn no_distortion(d: &[f64; 5]) -> bool {
    d.iter().all(|c| *c == 0.0)
}

/// What a calibrated stereo head knows of itself: both cameras' intrinsics and the right
/// camera's pose in the left camera's frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RigCalibration {
    pub left: Intrinsics,
    pub right: Intrinsics,
    pub left_from_right: WirePose,
}

/// `capture`'s reply: the stereo pair as 8-bit grey PNGs, base64.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaptureReply {
    pub left_png_b64: String,
    pub right_png_b64: String,
    /// The cameras' calibration file, if the server was given one (`serve --cameras`), as a
    /// camera driver publishes its calibration; without one the cameras are uncalibrated and
    /// the client must measure them (`marvin calibrate cameras`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<RigCalibration>,
    pub sim_time_s: f64,
}

/// `move`'s (and `home`'s) reply: where the robot says its gripper is, from its joint encoders.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MoveReply {
    pub base_from_gripper: WirePose,
    pub joints: BTreeMap<String, f64>,
    /// Simulated time the motion took, seconds.
    pub motion_s: f64,
    /// Worst joint tracking error on the way (metres for zed, radians for the rest).
    pub max_tracking_error: f64,
}

/// `take_tool`'s and `stow_tool`'s reply.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ToolReply {
    /// The tool in the gripper now, if any.
    pub holding: Option<String>,
    /// The jaws' opening now, mm.
    pub jaw_mm: f64,
}

/// How a pick went, judged from the cell: `placed`, `miss`, `slip`, `drop`, `outside_bin`,
/// `wrong_part` (another object than the one whose pose the request carried was lifted).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PickOutcomeKind {
    Placed,
    Miss,
    Slip,
    Drop,
    OutsideBin,
    WrongPart,
}

/// `pick`'s reply.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PickReply {
    /// How it went; absent for `plan_only`.
    pub outcome: Option<PickOutcomeKind>,
    pub detail: Option<String>,
    /// Wall time of inverse kinematics and path planning, milliseconds.
    pub plan_ms: f64,
    /// Simulated time of the motion, seconds.
    pub motion_s: f64,
    /// Which of the candidate grasps the plan used (0 = the one given), and its tilt about the
    /// jaw axis.
    pub grasp_index: usize,
    /// The jaws' opening once closed, mm.
    pub closed_opening_mm: Option<f64>,
    /// How far the fingertips reach past the object's centre of mass along the approach, mm
    /// (negative: they stop short of it, holding the part nearer its top than its weight).
    #[serde(default)]
    pub grip_past_com_mm: Option<f64>,
    /// The path planned for the tool centre point, in `base` (metres): each move's waypoints in
    /// order, from the approach to the retreat.
    #[serde(default)]
    pub tcp_path_base_m: Vec<[f64; 3]>,
}

/// One object as the simulation has it (evaluation only).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthObject {
    pub id: u32,
    pub model: String,
    pub world_from_model: WirePose,
    pub in_bin: bool,
}

/// `truth`'s reply (evaluation only).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthReply {
    pub objects: Vec<TruthObject>,
    /// Where the held tool sits in the gripper (`gripper_from_tool`), from the physics.
    pub tool_in_gripper: Option<WirePose>,
    pub world_from_base: WirePose,
    pub world_from_cam: WirePose,
    pub cam_from_base: WirePose,
    /// Why the scene the cell started from had not settled (still moving at the time limit, or
    /// objects wedged into each other), if it had not.
    #[serde(default)]
    pub unsettled: Option<String>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn code_of(line: &str) -> Option<ErrorCode> {
        parse_request(line.as_bytes()).1.err().map(|e| e.code)
    }

    #[test]
    fn requests_parse_with_their_ids() {
        let (id, r) = parse_request(br#"{"id":7,"op":"status"}"#);
        assert_eq!((id, r), (Value::from(7), Ok(Request::Status {})));
        let (id, r) = parse_request(br#"{"op":"hello","protocol":1,"token":"t"}"#);
        assert_eq!(id, Value::Null);
        assert_eq!(r, Ok(Request::Hello { protocol: 1, token: Some("t".into()) }));
        let line = r#"{"op":"pick","model":"block","grasp":{"frame":"cam","translation_m":[0,0,0.8],"rotation_xyzw":[0,0,0,1],"jaw_mm":30},"place":{"bin":"bin"}}"#;
        let Ok(Request::Pick(p)) = parse_request(line.as_bytes()).1 else { panic!("not a pick") };
        assert_eq!((p.model.as_str(), p.grasp.jaw_mm, p.grasp.frame), ("block", 30.0, Some(Frame::Cam)));
    }

    #[test]
    fn each_kind_of_bad_line_has_its_code() {
        assert_eq!(code_of("{"), Some(ErrorCode::BadJson));
        assert_eq!(code_of("[1,2]"), Some(ErrorCode::BadJson));
        assert_eq!(code_of(r#"{"op":"status","x":NaN}"#), Some(ErrorCode::BadJson));
        assert_eq!(parse_request(&[0xff, 0xfe, b'{']).1.unwrap_err().code, ErrorCode::BadJson);
        assert_eq!(code_of(r#"{"op":"dance"}"#), Some(ErrorCode::UnknownOp));
        assert_eq!(code_of(r#"{"id":1}"#), Some(ErrorCode::BadRequest));
        assert_eq!(code_of(r#"{"op":5}"#), Some(ErrorCode::BadRequest));
        assert_eq!(code_of(r#"{"op":"hello","protocol":"one"}"#), Some(ErrorCode::BadRequest));
        assert_eq!(code_of(r#"{"op":"status","extra":1}"#), Some(ErrorCode::BadRequest));
        assert_eq!(code_of(r#"{"op":"hello","protocol":1,"extra":1}"#), Some(ErrorCode::BadRequest));
        assert_eq!(code_of(r#"{"op":"move","tool":null,"velocity":2}"#), Some(ErrorCode::BadRequest));
        assert_eq!(code_of(r#"{"op":"set_hand_eye"}"#), Some(ErrorCode::BadRequest));
    }

    #[test]
    fn poses_must_be_finite_near_and_unit() {
        let pose = |t: [f64; 3], q: [f64; 4]| WirePose { frame: Some(Frame::Base), translation_m: t, rotation_xyzw: q };
        assert!(pose([0.1, 0.2, 0.3], [0.0, 0.0, 0.0, 1.0]).to_isometry("p").is_ok());
        assert!(pose([0.0; 3], [0.0, 0.0, 0.0, 1.0005]).to_isometry("p").is_ok());
        for bad in [
            pose([f64::NAN, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]),
            pose([1e300, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]),
            pose([0.0; 3], [0.0, 0.0, 0.0, 1.01]),
            pose([0.0; 3], [0.0; 4]),
            pose([0.0; 3], [f64::INFINITY, 0.0, 0.0, 1.0]),
        ] {
            let e = bad.to_isometry("grasp").unwrap_err();
            assert_eq!(e.code, ErrorCode::BadRequest);
            assert!(e.message.contains("`grasp`"), "{}", e.message);
        }
        let e = pose([0.0; 3], [0.0, 0.0, 0.0, 1.0]).in_frames("tool", &[Frame::Cam]).unwrap_err();
        assert!(e.message.contains("frame"), "{}", e.message);
    }

    #[test]
    fn a_pose_goes_over_the_wire_and_back() {
        let iso =
            Isometry3::from_parts(Translation3::new(0.1, -0.2, 0.3), UnitQuaternion::from_euler_angles(0.3, -1.1, 2.0));
        let wire: WirePose =
            serde_json::from_str(&serde_json::to_string(&WirePose::new(Some(Frame::Cam), &iso)).unwrap()).unwrap();
        let back = wire.to_isometry("p").unwrap();
        assert!((back.translation.vector - iso.translation.vector).norm() < 1e-15);
        assert!(back.rotation.angle_to(&iso.rotation) < 1e-12);
    }

    #[test]
    fn replies_echo_the_id() {
        let parsed = |s: String| serde_json::from_str::<Value>(&s).unwrap();
        let ok = reply_line(&Value::from("a"), &Ok(serde_json::json!({"x": 1})));
        assert_eq!(parsed(ok), serde_json::json!({"id": "a", "ok": true, "x": 1}));
        let err = reply_line(&Value::Null, &Err(WireError::new(ErrorCode::Busy, "m")));
        assert_eq!(
            parsed(err),
            serde_json::json!({"id": null, "ok": false, "error": {"code": "busy", "message": "m"}})
        );
    }
}
