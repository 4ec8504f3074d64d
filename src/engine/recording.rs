//! Rerun recordings of a run, for looking at it: `marvin run --rerun FILE.rrd` writes one,
//! `--rerun-connect [URL]` streams to a running viewer. Everything is logged in the robot's base
//! frame (entity `cell`), on a `cycle` sequence and a `sim_time` timeline:
//!
//! - `cell/camera/left`, `cell/camera/right`: the cameras as pinholes where the calibration puts
//!   them, with each captured image; under the left image its edgels and 2D lines;
//! - `cell/lines3d`: the 3D lines of each capture;
//! - `cell/located/<k>`: each located part's wireframe, labelled with its model, and its grasp
//!   frame;
//! - `cell/bins`: the bins, as the server's layout gives them; `cell/fixed/*`: the table and
//!   the bins' walls from the world file;
//! - `cell/arm/<link>`: the arm's links (the URDF's collision shapes) where its kinematics put
//!   them for the joints the server reports at the end of each cycle;
//! - `cell/path`: the path planned for the tool centre point in each pick, as the server sends it;
//! - `cell/truth/objects/<id>`: with a server started here, the objects' meshes where the
//!   simulation has them after each cycle (evaluation's view, logged after the fact);
//! - `cell/calibration`: the flag sightings, the solved camera pose, and (locally) the true one;
//! - `rig`: with `marvin calibrate cameras --rerun`, the cameras as solved (the left camera's
//!   frame), each view's images with the corners found, where the solution reprojects them and
//!   the residuals (drawn 100 times longer), and the boards, on a `view` sequence;
//! - `stages/<stage>`: each cycle's stage times, ms; `joints/<joint>`: the arm's joints at the
//!   end of each cycle; `log`: a text log of events.
//!
//! A default blueprint lays out the 3D view, the two camera views and the log. `marvin locate
//! --rerun` records its rendered scene with the same entities ([`Recording::stereo`] after
//! [`Recording::frame`]), `marvin calibrate --rerun` its calibration. Built without the `rerun`
//! feature, asking for a recording is an error that says so.

use crate::engine::calibrate::Calibration;
use crate::engine::calibrate_cameras::CameraCalibration;
use crate::engine::perception::Pair;
use crate::engine::run::Cycle;
use crate::protocol::{BinBox, CaptureReply, TruthReply};
use nalgebra::Isometry3;
use vision::front_end::FrontEnd;
use vision::matcher::Located;

/// Where a recording goes.
#[derive(Debug, Clone)]
pub enum Sink {
    File(std::path::PathBuf),
    /// A running viewer (its gRPC URL; the default one when `None`).
    Viewer(Option<String>),
}

#[cfg(feature = "rerun")]
pub use with_rerun::Recording;
#[cfg(not(feature = "rerun"))]
pub use without_rerun::Recording;

#[cfg(feature = "rerun")]
mod with_rerun {
    use super::*;
    use anyhow::Context;
    use nalgebra::Point3;
    use rerun::blueprint::{Blueprint, Horizontal, Spatial2DView, Spatial3DView, TextLogView, Vertical};

    /// Points at `pose`, as rerun takes them.
    fn points(pose: &Isometry3<f64>, ps: impl IntoIterator<Item = Point3<f64>>) -> Vec<[f32; 3]> {
        ps.into_iter().map(|p| pose * p).map(|p| [p.x as f32, p.y as f32, p.z as f32]).collect()
    }

    /// A recording in progress.
    pub struct Recording {
        rec: rerun::RecordingStream,
        base_from_cam: Option<Isometry3<f64>>,
        located_logged: usize,
        arm_logged: bool,
    }

    /// A mesh moved by `pose`, as rerun takes it.
    fn mesh3d(m: &mesh::TriMesh, pose: &Isometry3<f64>, albedo: u32) -> rerun::Mesh3D {
        rerun::Mesh3D::new(points(pose, m.vertices.iter().copied()))
            .with_triangle_indices(m.triangles.iter().map(|t| rerun::datatypes::UVec3D::new(t[0], t[1], t[2])))
            .with_albedo_factor(albedo)
    }

    /// A URDF collision primitive as a mesh in its link's frame (URDF cylinders run along z,
    /// rapier's along y).
    fn primitive_mesh(shape: &robot::arm::LinkShape) -> Option<mesh::TriMesh> {
        use rapier3d::prelude::ColliderBuilder;
        use robot::arm::Primitive;
        let (builder, turn) = match shape.primitive {
            Primitive::Box { half_extents: h } => (ColliderBuilder::cuboid(h.x as f32, h.y as f32, h.z as f32), false),
            Primitive::Cylinder { radius, half_length } => {
                (ColliderBuilder::cylinder(half_length as f32, radius as f32), true)
            }
            Primitive::Sphere { radius } => (ColliderBuilder::ball(radius as f32), false),
            Primitive::Capsule { radius, half_length } => {
                (ColliderBuilder::capsule_z(half_length as f32, radius as f32), false)
            }
        };
        let along_z = if turn {
            Isometry3::rotation(nalgebra::Vector3::x() * std::f64::consts::FRAC_PI_2)
        } else {
            Isometry3::identity()
        };
        let collider = builder.position(sim::convert::pose(&(shape.link_from_shape * along_z))).build();
        sim::shape_mesh::collider_mesh(&collider, 0.35)
    }

    fn transform(pose: &Isometry3<f64>) -> rerun::Transform3D {
        let t = pose.translation.vector;
        let q = pose.rotation.coords;
        rerun::Transform3D::from_translation_rotation(
            [t.x as f32, t.y as f32, t.z as f32],
            rerun::Quaternion::from_xyzw([q.x as f32, q.y as f32, q.z as f32, q.w as f32]),
        )
    }

    impl Recording {
        pub fn start(sink: &Sink) -> anyhow::Result<Recording> {
            let builder = rerun::RecordingStreamBuilder::new("marvin");
            let rec = match sink {
                Sink::File(path) => {
                    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
                        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
                    }
                    builder.save(path).with_context(|| format!("{}: cannot write a recording", path.display()))?
                }
                Sink::Viewer(None) => builder.connect_grpc().context("connecting to a rerun viewer")?,
                Sink::Viewer(Some(url)) => builder
                    .connect_grpc_opts(url.clone())
                    .with_context(|| format!("connecting to a rerun viewer at {url}"))?,
            };
            rec.log_static("cell", &rerun::ViewCoordinates::RIGHT_HAND_Z_UP())?;
            let blueprint = Blueprint::new(Horizontal::new([
                Spatial3DView::new("cell").with_origin("cell").into(),
                Vertical::new([
                    Spatial2DView::new("left camera").with_origin("cell/camera/left/image").into(),
                    Spatial2DView::new("right camera").with_origin("cell/camera/right/image").into(),
                    TextLogView::new("log").with_origin("log").into(),
                ])
                .into(),
            ]));
            blueprint.send(&rec, rerun::blueprint::BlueprintActivation::default())?;
            Ok(Recording { rec, base_from_cam: None, located_logged: 0, arm_logged: false })
        }

        pub fn text(&self, line: &str) -> anyhow::Result<()> {
            Ok(self.rec.log("log", &rerun::TextLog::new(line))?)
        }

        pub fn at(&self, cycle: usize, sim_time_s: f64) {
            self.rec.set_time_sequence("cycle", cycle as i64);
            self.rec.set_duration_secs("sim_time", sim_time_s);
        }

        /// The calibration: sightings (where vision saw the flag, and where the robot's
        /// kinematics and the solution put it), the solved camera, and the true one if known.
        pub fn calibration(&mut self, c: &Calibration) -> anyhow::Result<()> {
            let s = &c.solution;
            let base_from_cam = s.cam_from_base.inverse();
            self.base_from_cam = Some(base_from_cam);
            let seen: Vec<[f32; 3]> = c
                .poses
                .iter()
                .filter(|p| p.used)
                .filter_map(|p| p.cam_from_flag)
                .map(|f| points(&(base_from_cam * f), [Point3::origin()])[0])
                .collect();
            let predicted: Vec<[f32; 3]> = c
                .poses
                .iter()
                .filter(|p| p.used)
                .filter_map(|p| p.base_from_gripper)
                .map(|b| points(&(b * s.gripper_from_flag), [Point3::origin()])[0])
                .collect();
            self.rec.log(
                "cell/calibration/sightings/seen",
                &rerun::Points3D::new(seen).with_radii([0.003]).with_colors([0x33AAFFFF]),
            )?;
            self.rec.log(
                "cell/calibration/sightings/robot",
                &rerun::Points3D::new(predicted).with_radii([0.002]).with_colors([0xFFAA33FF]),
            )?;
            self.rec.log("cell/calibration/solved_camera", &transform(&base_from_cam))?;
            self.text(&format!(
                "calibrated: {} of {} poses used, residuals {:.3} mm / {:.3} deg RMS",
                s.used.iter().filter(|u| **u).count(),
                c.poses.len(),
                s.residual_mm_rms,
                s.residual_deg_rms
            ))
        }

        /// Where the camera truly is (evaluation's view, after the fact), beside the solved pose.
        pub fn true_camera(&self, true_cam_from_base: &Isometry3<f64>) -> anyhow::Result<()> {
            Ok(self.rec.log("cell/calibration/true_camera", &transform(&true_cam_from_base.inverse()))?)
        }

        /// A camera pose known from a file (no sightings to show).
        pub fn calibration_known(&mut self, cam_from_base: &Isometry3<f64>) -> anyhow::Result<()> {
            self.base_from_cam = Some(cam_from_base.inverse());
            self.rec.log("cell/calibration/solved_camera", &transform(&cam_from_base.inverse()))?;
            self.text("hand-eye transform from a file")
        }

        pub fn bins(&self, bins: &[BinBox]) -> anyhow::Result<()> {
            let centres: Vec<[f32; 3]> = bins.iter().map(|b| b.centre_base_m.map(|v| v as f32)).collect();
            let halves: Vec<[f32; 3]> = bins.iter().map(|b| b.size_m.map(|v| v as f32 / 2.0)).collect();
            let labels: Vec<String> = bins.iter().map(|b| format!("bin {}", b.name)).collect();
            Ok(self.rec.log_static(
                "cell/bins",
                &rerun::Boxes3D::from_centers_and_half_sizes(centres, halves).with_labels(labels),
            )?)
        }

        /// A capture: both cameras with their images, the left one's edgels and 2D lines, the
        /// 3D lines in the cell.
        pub fn capture(&mut self, capture: &CaptureReply, pair: &Pair, fe: &FrontEnd) -> anyhow::Result<()> {
            use base64::Engine;
            let decode =
                |png: &str| base64::engine::general_purpose::STANDARD.decode(png).context("the capture's image");
            let pngs = [decode(&capture.left_png_b64)?, decode(&capture.right_png_b64)?];
            self.stereo(pngs, pair, fe)
        }

        /// The cell's frame seen from the left camera, for recordings made without a calibration
        /// (`marvin locate` renders its scene: the robot's base frame from the world file).
        pub fn frame(&mut self, base_from_cam: &Isometry3<f64>) {
            self.base_from_cam = Some(*base_from_cam);
        }

        /// A stereo pair (its images as PNG files' bytes) and what the front end made of it.
        pub fn stereo(&mut self, pngs: [Vec<u8>; 2], pair: &Pair, fe: &FrontEnd) -> anyhow::Result<()> {
            let Some(base_from_cam) = self.base_from_cam else { return Ok(()) };
            let [left_png, right_png] = pngs;
            for (side, cam, png) in [("left", &pair.calib.left, left_png), ("right", &pair.calib.right, right_png)] {
                let path = format!("cell/camera/{side}");
                self.rec.log(path.as_str(), &transform(&(base_from_cam * cam.world_from_cam)))?;
                let pinhole = rerun::Pinhole::from_focal_length_and_resolution(
                    [cam.fx as f32, cam.fy as f32],
                    [cam.width as f32, cam.height as f32],
                )
                .with_principal_point([cam.cx as f32, cam.cy as f32]);
                self.rec.log(format!("{path}/image").as_str(), &pinhole)?;
                self.rec.log(format!("{path}/image").as_str(), &rerun::EncodedImage::from_file_contents(png))?;
            }
            let edgels: Vec<[f32; 2]> = fe.left.edgels.iter().map(|e| [e.x, e.y]).collect();
            self.rec.log(
                "cell/camera/left/image/edgels",
                &rerun::Points2D::new(edgels).with_radii([0.5]).with_colors([0x00FF00FF]),
            )?;
            let lines2d: Vec<[[f32; 2]; 2]> = fe.lines2d.iter().map(|l| [l.start, l.end]).collect();
            self.rec
                .log("cell/camera/left/image/lines2d", &rerun::LineStrips2D::new(lines2d).with_colors([0xFFFF00FF]))?;
            let lines3d: Vec<Vec<[f32; 3]>> =
                fe.lines3d.iter().map(|l| points(&base_from_cam, [l.start(), l.end()])).collect();
            self.rec.log("cell/lines3d", &rerun::LineStrips3D::new(lines3d).with_colors([0xFF8800FF]))?;
            // The lines believed shadows or texture, apart and dim, so that they can be checked.
            let set_apart: Vec<Vec<[f32; 3]>> =
                fe.set_apart.iter().map(|l| points(&base_from_cam, [l.start(), l.end()])).collect();
            self.rec.log("cell/lines3d_set_apart", &rerun::LineStrips3D::new(set_apart).with_colors([0x8080FFFF]))?;
            Ok(())
        }

        /// The parts located: wireframes labelled with their models (and, where `in_doubt` says so,
        /// as in doubt: a turn of the part fits as well), and grasp frames.
        pub fn located(
            &mut self,
            located: &[Located],
            in_doubt: &[bool],
            library: &mesh::Library,
        ) -> anyhow::Result<()> {
            let Some(base_from_cam) = self.base_from_cam else { return Ok(()) };
            for k in located.len()..self.located_logged {
                self.rec.log(format!("cell/located/{k}").as_str(), &rerun::Clear::recursive())?;
            }
            self.located_logged = located.len();
            for (k, l) in located.iter().enumerate() {
                let Some(model) = library.get(&l.model) else { continue };
                let pose = base_from_cam * l.cam_from_model;
                let strips: Vec<Vec<[f32; 3]>> = model.wireframe.iter().map(|s| points(&pose, [s.a, s.b])).collect();
                let doubt = if in_doubt.get(k).copied().unwrap_or(false) { ", in doubt" } else { "" };
                let label = format!("{} ({:.0}% seen{doubt})", l.model, l.support_fraction * 100.0);
                self.rec.log(
                    format!("cell/located/{k}").as_str(),
                    &rerun::LineStrips3D::new(strips).with_colors([0x00FFFFFF]).with_labels([label]),
                )?;
                if let Some((cam_from_gripper, _)) = l.grasps.first() {
                    let g = base_from_cam * cam_from_gripper;
                    let o = points(&g, [Point3::origin()])[0];
                    let axes: Vec<[f32; 3]> = [nalgebra::Vector3::x(), nalgebra::Vector3::y(), nalgebra::Vector3::z()]
                        .iter()
                        .map(|a| {
                            let v = g.rotation * a * 0.03;
                            [v.x as f32, v.y as f32, v.z as f32]
                        })
                        .collect();
                    self.rec.log(
                        format!("cell/located/{k}/grasp").as_str(),
                        &rerun::Arrows3D::from_vectors(axes)
                            .with_origins([o; 3])
                            .with_colors([0xFF0000FF, 0x00FF00FF, 0x0000FFFF]),
                    )?;
                }
            }
            Ok(())
        }

        /// A cycle's stage times, the arm's joints at its end, and its outcome.
        pub fn cycle(&self, c: &Cycle, line: &str) -> anyhow::Result<()> {
            self.rec.set_duration_secs("sim_time", c.sim_time_s);
            for (joint, value) in &c.joints {
                self.rec.log(format!("joints/{joint}").as_str(), &rerun::Scalars::single(*value))?;
            }
            for (stage, ms) in &c.timings_ms {
                self.rec.log(format!("stages/{stage}").as_str(), &rerun::Scalars::single(*ms))?;
            }
            self.rec.log("stages/vision", &rerun::Scalars::single(c.vision_ms()))?;
            if let Some(Ok(reply)) = &c.outcome {
                let path: Vec<[f32; 3]> = reply.tcp_path_base_m.iter().map(|p| p.map(|v| v as f32)).collect();
                self.rec.log("cell/path", &rerun::LineStrips3D::new([path]).with_colors([0xFF00FFFF]))?;
            }
            self.text(line)
        }

        /// Where the simulation has the objects (evaluation's view, after the fact).
        pub fn truth(&self, truth: &TruthReply, library: &mesh::Library) -> anyhow::Result<()> {
            let base_from_world = truth.world_from_base.to_isometry("world_from_base")?.inverse();
            for o in &truth.objects {
                let Some(model) = library.get(&o.model) else { continue };
                let pose = base_from_world * o.world_from_model.to_isometry("world_from_model")?;
                let path = format!("cell/truth/objects/{}", o.id);
                let positions = points(&Isometry3::identity(), model.mesh.vertices.iter().copied());
                self.rec.log_static(
                    path.as_str(),
                    &rerun::Mesh3D::new(positions)
                        .with_triangle_indices(
                            model.mesh.triangles.iter().map(|t| rerun::datatypes::UVec3D::new(t[0], t[1], t[2])),
                        )
                        .with_albedo_factor(0xB0B0B0FF),
                )?;
                self.rec.log(path.as_str(), &transform(&pose))?;
            }
            Ok(())
        }

        /// The cell's fixed parts from the world file (table, bin walls; not the floor), in the
        /// base frame, once.
        pub fn cell_layout(&self, scn: &sim::Scenario) -> anyhow::Result<()> {
            let Some(robot) = &scn.world.robot else { return Ok(()) };
            let base_from_world = robot.world_from_base().inverse();
            for b in sim::scene::static_boxes(&scn.world).iter().filter(|b| b.name != "floor") {
                let m = b.mesh();
                let path = format!("cell/fixed/{}", b.name.replace(' ', "_"));
                self.rec.log_static(path.as_str(), &mesh3d(&m, &base_from_world, 0x808080FF))?;
            }
            Ok(())
        }

        /// The arm's links where its kinematics put them for joints `q` and jaw `opening`
        /// (meshes of the URDF's collision shapes, logged once; their poses each time).
        pub fn arm(&mut self, arm: &robot::Arm, q: &robot::Joints, opening: f64) -> anyhow::Result<()> {
            if !self.arm_logged {
                for link in &arm.links {
                    let mut m = mesh::TriMesh::default();
                    for shape in &link.shapes {
                        if let Some(piece) = primitive_mesh(shape) {
                            m.append(&piece);
                        }
                    }
                    if !m.triangles.is_empty() {
                        let path = format!("cell/arm/{}", link.name);
                        self.rec.log_static(path.as_str(), &mesh3d(&m, &Isometry3::identity(), 0x5A6A80FF))?;
                    }
                }
                self.arm_logged = true;
            }
            for (link, pose) in arm.links.iter().zip(arm.link_poses(q, opening)) {
                if !link.shapes.is_empty() {
                    self.rec.log(format!("cell/arm/{}", link.name).as_str(), &transform(&pose))?;
                }
            }
            Ok(())
        }

        /// A camera calibration, view by view on a `view` sequence: both images with the corners
        /// found (green) and where the solution reprojects them (red), the residuals drawn 100
        /// times longer; in 3D (`rig`, the left camera's frame) both cameras as solved and every
        /// board's corners where the solution puts them.
        pub fn camera_calibration(&mut self, c: &CameraCalibration) -> anyhow::Result<()> {
            let s = &c.solution;
            let board = camera_calib::Board::LIBRARY;
            let corners = board.points();
            let left_from_right = s.right_from_left.inverse();
            for (side, k, pose) in [("left", &s.left, Isometry3::identity()), ("right", &s.right, left_from_right)] {
                let path = format!("rig/camera/{side}");
                self.rec.log_static(path.as_str(), &transform(&pose))?;
                let pinhole = rerun::Pinhole::from_focal_length_and_resolution(
                    [k.fx as f32, k.fy as f32],
                    [c.size[0] as f32, c.size[1] as f32],
                )
                .with_principal_point([k.cx as f32, k.cy as f32]);
                self.rec.log_static(format!("{path}/image").as_str(), &pinhole)?;
            }
            for (v, view) in c.views.iter().enumerate() {
                self.rec.set_time_sequence("view", v as i64);
                self.text(&format!("pose {}: {}", v + 1, view.note))?;
                let Some(left_from_board) = s.boards.get(v).copied().flatten() else { continue };
                self.rec.log(
                    "rig/boards",
                    &rerun::Points3D::new(points(&left_from_board, corners.iter().copied())).with_radii([0.0015]),
                )?;
                let sides = [
                    ("left", &s.left, left_from_board, &view.corners.left, view.images.as_ref().map(|i| &i.0)),
                    (
                        "right",
                        &s.right,
                        s.right_from_left * left_from_board,
                        &view.corners.right,
                        view.images.as_ref().map(|i| &i.1),
                    ),
                ];
                for (side, k, cam_from_board, found, image) in sides {
                    let path = format!("rig/camera/{side}/image");
                    if let Some(img) = image {
                        self.rec.log(
                            path.as_str(),
                            &rerun::Image::from_l8(img.as_raw().clone(), [img.width(), img.height()]),
                        )?;
                    }
                    let Some(found) = found else {
                        self.rec.log(format!("{path}/corners").as_str(), &rerun::Clear::recursive())?;
                        continue;
                    };
                    let predicted: Vec<[f32; 2]> = corners
                        .iter()
                        .filter_map(|p| k.project(&(cam_from_board * p)))
                        .map(|q| [q.x as f32, q.y as f32])
                        .collect();
                    let seen: Vec<[f32; 2]> = found.iter().map(|q| [q.x as f32, q.y as f32]).collect();
                    let residuals: Vec<[f32; 2]> = predicted
                        .iter()
                        .zip(&seen)
                        .map(|(p, q)| [100.0 * (p[0] - q[0]), 100.0 * (p[1] - q[1])])
                        .collect();
                    self.rec.log(
                        format!("{path}/corners/found").as_str(),
                        &rerun::Points2D::new(seen.clone()).with_radii([1.0]).with_colors([0x33DD33FF]),
                    )?;
                    self.rec.log(
                        format!("{path}/corners/reprojected").as_str(),
                        &rerun::Points2D::new(predicted).with_radii([0.6]).with_colors([0xFF3333FF]),
                    )?;
                    self.rec.log(
                        format!("{path}/corners/residual_x100").as_str(),
                        &rerun::Arrows2D::from_vectors(residuals).with_origins(seen).with_colors([0xFFAA00FF]),
                    )?;
                }
            }
            self.text(&format!(
                "cameras calibrated: reprojection RMS {:.3} px (left {:.3}, right {:.3})",
                s.rms_px, s.left_rms_px, s.right_rms_px
            ))
        }

        /// Flushes and closes the recording, so that `rerun rrd verify` accepts the file.
        pub fn finish(self) -> anyhow::Result<()> {
            self.rec.flush_blocking().map_err(|e| anyhow::anyhow!("closing the recording: {e}"))?;
            drop(self.rec);
            Ok(())
        }
    }
}

#[cfg(not(feature = "rerun"))]
mod without_rerun {
    use super::*;

    /// Without the `rerun` feature there are no recordings.
    pub struct Recording;

    impl Recording {
        pub fn start(_sink: &Sink) -> anyhow::Result<Recording> {
            anyhow::bail!(
                "this marvin was built without the `rerun` feature: rebuild with default features for --rerun"
            )
        }
        pub fn text(&self, _line: &str) -> anyhow::Result<()> {
            Ok(())
        }
        pub fn at(&self, _cycle: usize, _sim_time_s: f64) {}
        pub fn calibration(&mut self, _c: &Calibration) -> anyhow::Result<()> {
            Ok(())
        }
        pub fn camera_calibration(&mut self, _c: &CameraCalibration) -> anyhow::Result<()> {
            Ok(())
        }
        pub fn true_camera(&self, _t: &Isometry3<f64>) -> anyhow::Result<()> {
            Ok(())
        }
        pub fn calibration_known(&mut self, _x: &Isometry3<f64>) -> anyhow::Result<()> {
            Ok(())
        }
        pub fn bins(&self, _bins: &[BinBox]) -> anyhow::Result<()> {
            Ok(())
        }
        pub fn capture(&mut self, _c: &CaptureReply, _p: &Pair, _fe: &FrontEnd) -> anyhow::Result<()> {
            Ok(())
        }
        pub fn frame(&mut self, _base_from_cam: &Isometry3<f64>) {}
        pub fn stereo(&mut self, _pngs: [Vec<u8>; 2], _p: &Pair, _fe: &FrontEnd) -> anyhow::Result<()> {
            Ok(())
        }
        pub fn located(&mut self, _l: &[Located], _doubt: &[bool], _lib: &mesh::Library) -> anyhow::Result<()> {
            Ok(())
        }
        pub fn cycle(&self, _c: &Cycle, _line: &str) -> anyhow::Result<()> {
            Ok(())
        }
        pub fn truth(&self, _t: &TruthReply, _lib: &mesh::Library) -> anyhow::Result<()> {
            Ok(())
        }
        pub fn cell_layout(&self, _scn: &sim::Scenario) -> anyhow::Result<()> {
            Ok(())
        }
        pub fn arm(&mut self, _arm: &robot::Arm, _q: &robot::Joints, _opening: f64) -> anyhow::Result<()> {
            Ok(())
        }
        pub fn finish(self) -> anyhow::Result<()> {
            Ok(())
        }
    }
}
