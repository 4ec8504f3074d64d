//! The robot server as a user meets it: a real `marvin serve` process driven over TCP, through a
//! whole session (ending with an object picked from a true pose and lying in the bin), and
//! through every kind of hostile input, after which it still answers and nothing has moved.

use marvin::engine::client::Client;
use marvin::eval::truth::AskTruth;
use marvin::protocol::{
    ErrorCode, Frame, MoveTarget, PickOutcomeKind, PickSpec, PlaceSpec, TruthReply, WireGrasp, WireObject, WirePose,
};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use serde_json::Value;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A `marvin serve` child process, killed when dropped.
struct Served {
    child: Child,
    addr: String,
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts `marvin serve worlds/widgets.toml` on a free loopback port and waits for its address.
fn serve(extra: &[&str]) -> Served {
    let world = concat!(env!("CARGO_MANIFEST_DIR"), "/worlds/widgets.toml");
    let mut child = Command::new(env!("CARGO_BIN_EXE_marvin"))
        .args(["serve", world, "--listen", "127.0.0.1:0", "--seed", "3"])
        .args(extra)
        .env("RUST_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("marvin serve starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let addr = line.trim().strip_prefix("listening on ").unwrap_or_else(|| panic!("unexpected first line {line:?}"));
    Served { addr: addr.to_string(), child }
}

fn connect(s: &Served) -> Client {
    Client::connect(&s.addr, Duration::from_secs(5)).unwrap()
}

/// A connection that the server has said hello on. The server frees a closed connection's
/// place when its thread sees the close, a moment after the client's: on a busy machine a
/// client right after a flood may be told `busy`, and tries again (for up to 10 s).
fn connect_when_free(s: &Served) -> Client {
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    loop {
        let mut c = connect(s);
        match c.hello(None) {
            Ok(_) => return c,
            Err(e) if e.wire().is_some_and(|w| w.code == ErrorCode::Busy) && std::time::Instant::now() < deadline => {
                std::thread::sleep(Duration::from_millis(100));
            }
            Err(e) => panic!("hello after the flood: {e:?}"),
        }
    }
}

fn iso(p: &WirePose) -> Isometry3<f64> {
    p.to_isometry("truth").unwrap()
}

/// A raw connection for what the typed client would never send.
struct Raw {
    reader: BufReader<TcpStream>,
    writer: TcpStream,
}

impl Raw {
    fn new(s: &Served) -> Raw {
        let stream = TcpStream::connect(&s.addr).unwrap();
        stream.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
        Raw { writer: stream.try_clone().unwrap(), reader: BufReader::new(stream) }
    }

    fn send(&mut self, bytes: &[u8]) -> Option<Value> {
        self.writer.write_all(bytes).ok()?;
        self.reply()
    }

    /// The next reply line, or `None` once the server has closed the connection.
    fn reply(&mut self) -> Option<Value> {
        let mut line = String::new();
        match self.reader.read_line(&mut line) {
            Ok(0) | Err(_) => None,
            Ok(_) => Some(serde_json::from_str(&line).unwrap_or_else(|e| panic!("reply not JSON ({e}): {line:?}"))),
        }
    }

    /// Whether the server has closed the connection (reads end, or are reset, within the
    /// timeout; a reset is how a close looks while the server left our bytes unread).
    fn closed(&mut self) -> bool {
        use std::io::ErrorKind::{ConnectionAborted, ConnectionReset};
        let mut rest = Vec::new();
        match self.reader.read_to_end(&mut rest) {
            Ok(_) => rest.is_empty(),
            Err(e) => matches!(e.kind(), ConnectionReset | ConnectionAborted),
        }
    }
}

fn code(reply: &Option<Value>) -> String {
    let r = reply.as_ref().expect("a reply");
    assert_eq!(r["ok"], Value::Bool(false), "expected an error reply, got {r}");
    r["error"]["code"].as_str().unwrap().to_string()
}

/// The objects' true poses and whether each is in a bin.
fn objects(t: &TruthReply) -> Vec<(u32, Isometry3<f64>, bool)> {
    t.objects.iter().map(|o| (o.id, iso(&o.world_from_model), o.in_bin)).collect()
}

#[test]
fn a_whole_session_ends_with_an_object_in_the_bin() {
    let served = serve(&["--truth"]);
    let mut c = connect(&served);
    let hello = c.hello(None).unwrap();
    assert_eq!(hello.protocol, 1);
    assert!(hello.models.iter().any(|m| m == "widget") && !hello.calibrated, "{hello:?}");
    let bin = hello.bins[0].clone();

    let status = c.status().unwrap();
    assert_eq!(status.joints.len(), 6);
    assert!((status.joints["zed"] - sim::arm::HOME[0]).abs() < 1e-3, "{status:?}");

    // The pair decodes to two 512x512 images with something in them.
    let pair = c.capture().unwrap();
    for b64 in [&pair.left_png_b64, &pair.right_png_b64] {
        use base64::Engine;
        let png = base64::engine::general_purpose::STANDARD.decode(b64).unwrap();
        let img = image::load_from_memory(&png).unwrap().into_luma8();
        assert_eq!(img.dimensions(), (512, 512));
        let (lo, hi) = img.pixels().fold((255u8, 0u8), |(lo, hi), p| (lo.min(p.0[0]), hi.max(p.0[0])));
        assert!(hi - lo > 100, "a flat image: {lo}..{hi}");
    }
    // A server given no camera calibration file tells nothing of its cameras: they are measured.
    assert!(pair.calibration.is_none(), "{:?}", pair.calibration);

    // A move reports where the gripper went, from the encoders: near where it was sent.
    let target = Isometry3::from_parts(
        Translation3::new(0.30, 0.15, 0.45),
        UnitQuaternion::from_euler_angles(std::f64::consts::PI, 0.0, 0.3),
    );
    let moved = c
        .move_to(MoveTarget { tool: Some(WirePose::new(Some(Frame::Base), &target)), joints: None, speed: None })
        .unwrap();
    let reached = iso(&moved.base_from_gripper);
    assert!((reached.translation.vector - target.translation.vector).norm() < 2e-3, "{reached} vs {target}");
    assert!(reached.rotation.angle_to(&target.rotation) < 0.01);

    // Before the hand-eye transform, a cam-frame pick is refused and nothing moves.
    let truth = c.truth().unwrap();
    let cam_from_base = iso(&truth.cam_from_base);
    let base_from_world = iso(&truth.world_from_base).inverse();
    let lib = mesh::Library::load_default().unwrap();
    let spec_for = |id: u32, t: &TruthReply| {
        let o = t.objects.iter().find(|o| o.id == id).unwrap();
        let cam_from_model = cam_from_base * base_from_world * iso(&o.world_from_model);
        let g = &lib.get(&o.model).unwrap().grasps[0];
        let others = t.objects.iter().filter(|x| x.id != id).map(|x| WireObject {
            model: x.model.clone(),
            pose: WirePose::new(Some(Frame::Cam), &(cam_from_base * base_from_world * iso(&x.world_from_model))),
        });
        PickSpec {
            model: o.model.clone(),
            grasp: WireGrasp::new(
                WirePose::new(Some(Frame::Cam), &(cam_from_model * g.model_from_gripper)),
                g.opening * 1e3,
            ),
            place: PlaceSpec { bin: bin.clone() },
            object: Some(WirePose::new(Some(Frame::Cam), &cam_from_model)),
            obstacles: others.collect(),
            plan_only: false,
        }
    };
    let highest = truth
        .objects
        .iter()
        .max_by(|a, b| iso(&a.world_from_model).translation.z.total_cmp(&iso(&b.world_from_model).translation.z))
        .unwrap()
        .id;
    let refused = c.pick(spec_for(highest, &truth)).unwrap_err();
    assert_eq!(refused.wire().map(|e| e.code), Some(ErrorCode::NotCalibrated), "{refused}");
    assert!(c.set_hand_eye(WirePose::new(None, &cam_from_base)).is_ok());
    assert!(c.status().unwrap().calibrated);

    // Planning alone moves nothing.
    let joints = c.status().unwrap().joints;
    let planned = c.pick(PickSpec { plan_only: true, ..spec_for(highest, &truth) }).unwrap();
    assert!(planned.outcome.is_none() && planned.plan_ms > 0.0, "{planned:?}");
    assert_eq!(c.status().unwrap().joints, joints);

    // The highest object, from its true pose in the cam frame, lands in the bin.
    let reply = c.pick(spec_for(highest, &truth)).unwrap();
    assert_eq!(reply.outcome, Some(PickOutcomeKind::Placed), "{reply:?}");
    // The path the server planned passes the object (its tool centre point within 5 cm of it).
    let object = truth.objects.iter().find(|o| o.id == highest).unwrap();
    let at = (base_from_world * iso(&object.world_from_model)).translation.vector;
    let nearest =
        reply.tcp_path_base_m.iter().map(|p| (nalgebra::Vector3::from(*p) - at).norm()).fold(f64::MAX, f64::min);
    assert!(nearest < 0.05, "the planned path stays {:.0} mm from the object", nearest * 1e3);
    let after = c.truth().unwrap();
    assert!(
        after.objects.iter().find(|o| o.id == highest).unwrap().in_bin,
        "the server said placed; the truth disagrees"
    );
    assert_eq!(after.objects.iter().filter(|o| o.in_bin).count(), 1, "one pick, one object in the bin");
    assert!(c.home().is_ok());
    c.bye().unwrap();
}

#[test]
fn hostile_input_gets_error_replies_and_moves_nothing() {
    let served = serve(&["--truth", "--idle-timeout-s", "2"]);
    let mut c = connect(&served);
    c.hello(None).unwrap();
    let (joints_before, truth_before) = (c.status().unwrap().joints, c.truth().unwrap());
    let base_from_world = iso(&truth_before.world_from_base).inverse();

    // One connection takes a run of bad lines, each answered, and stays open.
    let mut raw = Raw::new(&served);
    let cases: Vec<(&str, String)> = vec![
        ("bad_json", "{\"op\": \"status\"".into()),
        ("bad_json", "[1, 2, 3]".into()),
        ("bad_json", r#"{"op":"move","tool":{"frame":"base","translation_m":[NaN,0,0],"rotation_xyzw":[0,0,0,1]}}"#.into()),
        ("bad_json", r#"{"op":"move","tool":{"frame":"base","translation_m":[1e999,0,0],"rotation_xyzw":[0,0,0,1]}}"#.into()),
        ("bad_request", r#"{"op":"move","tool":{"frame":"base","translation_m":[1e300,0,0],"rotation_xyzw":[0,0,0,1]}}"#.into()),
        ("bad_request", r#"{"op":"move","tool":{"frame":"base","translation_m":[0.3,0,0.4],"rotation_xyzw":[0,0,0,2]}}"#.into()),
        ("bad_request", r#"{"op":"move","tool":{"frame":"base","translation_m":[0.3,0,0.4],"rotation_xyzw":[0,0,0,0]}}"#.into()),
        ("bad_request", r#"{"op":"move","tool":"up"}"#.into()),
        ("bad_request", r#"{"op":"move"}"#.into()),
        ("bad_request", r#"{"op":"move","joints":{"zed":"high"}}"#.into()),
        ("bad_request", r#"{"op":"move","joints":{"knee":0.1}}"#.into()),
        ("bad_request", r#"{"op":"move","joints":{"zed":0.5},"speed":0}"#.into()),
        ("bad_request", r#"{"op":"hello","protocol":-1}"#.into()),
        ("bad_request", r#"{"op":"set_hand_eye","cam_from_base":{"translation_m":[0,0],"rotation_xyzw":[0,0,0,1]}}"#.into()),
        ("bad_request", r#"{"op":7}"#.into()),
        ("bad_request", r#"{"op":"pick","model":"block","grasp":{"frame":"base","translation_m":[0.3,0,0.1],"rotation_xyzw":[1,0,0,0],"jaw_mm":-3},"place":{"bin":"a"}}"#.into()),
        ("bad_request", r#"{"op":"pick","model":"block","grasp":{"frame":"gripper","translation_m":[0.3,0,0.1],"rotation_xyzw":[1,0,0,0],"jaw_mm":30},"place":{"bin":"a"}}"#.into()),
        ("unknown_op", r#"{"op":"dance","id":"x"}"#.into()),
        ("unknown_model", r#"{"op":"pick","model":"teapot","grasp":{"frame":"base","translation_m":[0.3,0,0.1],"rotation_xyzw":[1,0,0,0],"jaw_mm":30},"place":{"bin":"a"}}"#.into()),
        ("unknown_bin", r#"{"op":"pick","model":"block","grasp":{"frame":"base","translation_m":[0.3,0,0.1],"rotation_xyzw":[1,0,0,0],"jaw_mm":30},"place":{"bin":"nowhere"}}"#.into()),
        ("not_calibrated", r#"{"op":"pick","model":"block","grasp":{"frame":"cam","translation_m":[0,0,0.9],"rotation_xyzw":[0,0,0,1],"jaw_mm":30},"place":{"bin":"a"}}"#.into()),
        ("unreachable", r#"{"op":"move","tool":{"frame":"base","translation_m":[3,0,0.4],"rotation_xyzw":[1,0,0,0]}}"#.into()),
        ("unreachable", r#"{"op":"move","joints":{"zed":5.0}}"#.into()),
        ("unreachable", r#"{"op":"pick","model":"block","grasp":{"frame":"base","translation_m":[2,2,0.1],"rotation_xyzw":[1,0,0,0],"jaw_mm":30},"place":{"bin":"a"}}"#.into()),
        ("bad_request", r#"{"op":"truth","extra":true}"#.into()),
    ];
    for (want, line) in &cases {
        let reply = raw.send(format!("{line}\n").as_bytes());
        assert_eq!(&code(&reply), want, "{line}");
    }
    // The id comes back even on an error.
    assert_eq!(raw.send(b"{\"id\":\"q7\",\"op\":\"dance\"}\n").unwrap()["id"], Value::from("q7"));

    // A tool pose inside the table: reachable, but every configuration there collides.
    let in_table = Isometry3::from_parts(
        Translation3::new(0.05, 0.05, -0.01),
        UnitQuaternion::from_euler_angles(std::f64::consts::PI, 0.0, 0.0),
    );
    let line =
        serde_json::json!({"op": "move", "tool": WirePose::new(Some(Frame::Base), &(base_from_world * in_table))});
    assert_eq!(code(&raw.send(format!("{line}\n").as_bytes())), "no_path");

    // Random binary, with and without newlines: error replies, the server unharmed.
    let mut junk = Raw::new(&served);
    let mut x = 0x2545F4914F6CDD1Du64;
    let bytes: Vec<u8> = (0..4000)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 32) as u8
        })
        .collect();
    junk.writer.write_all(&bytes).unwrap();
    junk.writer.write_all(b"\n").unwrap();
    let first = junk.reply();
    assert!(first.is_none() || code(&first) == "bad_json", "{first:?}");

    // A 2 MiB line: too_large, and the connection closes.
    let mut big = Raw::new(&served);
    let mut line = b"{\"op\":\"status\",\"pad\":\"".to_vec();
    line.resize(2 << 20, b'x');
    line.extend_from_slice(b"\"}\n");
    assert_eq!(code(&big.send(&line)), "too_large");
    assert!(big.closed());

    // A line never ended: the connection is closed once idle (2 s here, 30 s by default).
    let mut slow = Raw::new(&served);
    slow.writer.write_all(b"{\"op\":\"sta").unwrap();
    let t0 = Instant::now();
    assert!(slow.closed());
    assert!(t0.elapsed() < Duration::from_secs(10));

    // 50 clients at once: each is served or told `busy`, none hangs.
    let addr = served.addr.clone();
    let clients: Vec<_> = (0..50)
        .map(|_| {
            let addr = addr.clone();
            std::thread::spawn(move || {
                let mut c = Client::connect(&addr, Duration::from_secs(5)).unwrap();
                std::thread::sleep(Duration::from_millis(100));
                match c.status() {
                    Ok(s) => s.joints.len() == 6,
                    Err(e) => e.wire().is_some_and(|w| w.code == ErrorCode::Busy),
                }
            })
        })
        .collect();
    let answered = clients.into_iter().map(|h| h.join().unwrap()).filter(|ok| *ok).count();
    assert_eq!(answered, 50, "every client got status or busy");

    // After all of it: the server answers a new connection (the first has idled out), the arm
    // stands where it stood and no object has moved.
    drop((raw, junk, slow, c));
    let mut c = connect_when_free(&served);
    let status = c.status().unwrap();
    for (name, before) in &joints_before {
        assert!((status.joints[name] - before).abs() < 1e-9, "joint {name} moved: {before} -> {}", status.joints[name]);
    }
    let after = c.truth().unwrap();
    for ((id, a, _), (_, b, _)) in objects(&truth_before).iter().zip(objects(&after)) {
        assert!((a.translation.vector - b.translation.vector).norm() < 1e-9, "object {id} moved");
    }
}

#[test]
fn a_token_is_required_when_set_and_a_second_motion_is_busy() {
    let dir = std::env::temp_dir().join(format!("marvin-token-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let token_file = dir.join("token");
    std::fs::write(&token_file, "s3cret\n").unwrap();
    let served = serve(&["--token-file", token_file.to_str().unwrap()]);

    // Anything before hello, or a wrong token: unauthorized, and the connection closes.
    let mut raw = Raw::new(&served);
    assert_eq!(code(&raw.send(b"{\"op\":\"status\"}\n")), "unauthorized");
    assert!(raw.closed());
    let mut raw = Raw::new(&served);
    assert_eq!(code(&raw.send(b"{\"op\":\"hello\",\"protocol\":1,\"token\":\"guess\"}\n")), "unauthorized");
    assert!(raw.closed());
    let mut c = connect(&served);
    c.hello(Some("s3cret")).unwrap();

    // A slow move on one connection; a move on another meanwhile is busy, and status says so.
    let mut other = connect(&served);
    other.hello(Some("s3cret")).unwrap();
    let mover = std::thread::spawn(move || {
        let mut joints = std::collections::BTreeMap::new();
        joints.insert("shoulder".to_string(), 1.2);
        c.move_to(MoveTarget { tool: None, joints: Some(joints), speed: Some(0.05) })
    });
    let t0 = Instant::now();
    let mut saw_busy = false;
    while t0.elapsed() < Duration::from_secs(20) && !saw_busy {
        std::thread::sleep(Duration::from_millis(20));
        if other.status().unwrap().moving {
            let e = other.home().unwrap_err();
            assert_eq!(e.wire().map(|w| w.code), Some(ErrorCode::Busy), "{e}");
            saw_busy = true;
        }
    }
    assert!(saw_busy, "never saw the first motion running");
    let moved = mover.join().unwrap().unwrap();
    assert!((moved.joints["shoulder"] - 1.2).abs() < 0.01, "{moved:?}");
    assert!(other.home().is_ok(), "once the first motion is done, the next one runs");

    // An authorised shutdown stops the server, which exits 0.
    other.shutdown().unwrap();
    let mut served = served;
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = served.child.try_wait().unwrap() {
            break s;
        }
        assert!(t0.elapsed() < Duration::from_secs(20), "the server did not stop");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(status.success());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn off_loopback_without_a_token_the_server_refuses_to_start() {
    let world = concat!(env!("CARGO_MANIFEST_DIR"), "/worlds/widgets.toml");
    let out = Command::new(env!("CARGO_BIN_EXE_marvin"))
        .args(["serve", world, "--listen", "0.0.0.0:0"])
        .env_remove("MARVIN_TOKEN")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("without a token"), "{err}");
}

/// Started with `--cameras FILE`, the server's `capture` tells clients the measured cameras
/// (lenses included), as a camera driver publishes its calibration file; without it, nothing:
/// the renderer's own camera model never leaves the server.
#[test]
fn capture_carries_the_measured_cameras_when_the_server_is_given_them() {
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/camera-calib/tests/fixtures/seed3_cameras.json");
    let measured = camera_calib::file::CamerasFile::load(std::path::Path::new(file)).unwrap();
    for (extra, with_file) in [(vec!["--cameras", file], true), (vec![], false)] {
        let served = serve(&extra);
        let mut c = connect(&served);
        c.hello(None).unwrap();
        let calib = c.capture().unwrap().calibration;
        if let (true, Some(calib)) = (with_file, &calib) {
            assert_eq!(calib.left.distortion, measured.left.distortion);
            assert_eq!(calib.right.distortion, measured.right.distortion);
            assert!(
                (calib.left.fx - measured.left.fx).abs() < 1e-9 && (calib.right.cy - measured.right.cy).abs() < 1e-9
            );
            let rig = iso(&calib.left_from_right).inverse();
            let want = measured.right_from_left.isometry();
            assert!((rig.translation.vector - want.translation.vector).norm() < 1e-9);
        } else {
            assert!(!with_file && calib.is_none(), "with the file {with_file}: {calib:?}");
        }
    }
}

/// The server `marvin run` starts for itself answers a peer's `status` but not `truth`: the
/// run's judge reads the truth in-process, so nothing on the socket can.
#[test]
fn the_server_a_run_starts_serves_no_truth() {
    let world = concat!(env!("CARGO_MANIFEST_DIR"), "/worlds/ideal/widgets.toml");
    let mut child = Command::new(env!("CARGO_BIN_EXE_marvin"))
        .args(["run", world, "--seed", "3"])
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("marvin run starts");
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let prefix = "the run's robot server listens on ";
    let mut line = String::new();
    let addr = loop {
        line.clear();
        assert!(stderr.read_line(&mut line).unwrap() > 0, "marvin run ended without naming its server");
        if let Some(addr) = line.trim().strip_prefix(prefix) {
            break addr.to_string();
        }
    };
    let served = Served { child, addr };
    let mut c = connect(&served);
    c.hello(None).unwrap();
    let refused = c.truth().unwrap_err();
    assert_eq!(refused.wire().map(|e| e.code), Some(ErrorCode::BadRequest), "{refused}");
    c.status().expect("the same connection still answers status");
}
