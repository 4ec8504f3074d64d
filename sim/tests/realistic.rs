//! The realistic cell's images against independent computations: where the lens puts a point
//! (the `plumb_bob` formula), how wide the blur is at two depths (the thin lens's circle of
//! confusion), how the two cameras' gains differ (the world file), and that the depth maps of
//! a distorted camera are its true depths (parry ray casts through the true lens camera).
//! The shading, sensor noise and shadow tests are beside their modules (`lighting`, `sensor`).

use mesh::TriMesh;
use nalgebra::{Point3, Vector3};
use parry3d::math::{Pose, Vector};
use parry3d::query::{Ray, RayCast};
use parry3d::shape::TriMesh as ParryMesh;
use rand::{RngExt, SeedableRng, rngs::StdRng};
use sim::imaging::Imaging;
use sim::realism::Finish;
use sim::render::Frame;
use sim::{Scenario, Scene, WorldFile};
use std::path::Path;

/// Cameras 1 m over the table looking straight down, image `u` along world `x` (`up` is `+y`,
/// so image `v` runs along `-y`), with the effects, lens and right sensor given (TOML lines).
fn overhead_world(effects: &str, lens: &str, sensor_right: &str) -> WorldFile {
    let text = format!(
        r#"
realism = "ideal"
[effects]
{effects}
[table]
size_m = [1.4, 1.6]
height_m = 0.75
albedo = 0.0
[light]
direction = [0.0, 0.0, 1.0]
diffuse = 0.0
ambient = 1.0
[render]
noise_sigma = 0.0
[cameras.left]
focal_px = 1000.0
position_m = [0.0, 0.0, 1.0]
look_at_m = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
[cameras.left.lens]
{lens}
[cameras.left.mounting]
position_sigma_mm = 0.0
rotation_sigma_deg = 0.0
[cameras.right]
focal_px = 1000.0
position_m = [0.1, 0.0, 1.0]
look_at_m = [0.1, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
[cameras.right.lens]
{lens}
[cameras.right.sensor]
{sensor_right}
[cameras.right.mounting]
position_sigma_mm = 0.0
rotation_sigma_deg = 0.0
"#
    );
    WorldFile::parse(&text, "test.toml").unwrap_or_else(|e| panic!("{e}"))
}

/// A flat rectangle facing up (no sides to catch the light), centred at `(x, y)`, at height `z`.
fn plate(x: f64, y: f64, z: f64, half: [f64; 2], albedo: f32) -> TriMesh {
    let corner = |sx: f64, sy: f64| Point3::new(x + sx * half[0], y + sy * half[1], z);
    TriMesh {
        vertices: vec![corner(-1.0, -1.0), corner(1.0, -1.0), corner(1.0, 1.0), corner(-1.0, 1.0)],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
        albedo: vec![albedo; 2],
    }
}

fn draw(imaging: &Imaging, meshes: Vec<TriMesh>) -> (Frame, Frame) {
    let scene = imaging.scene(meshes.into_iter().enumerate().map(|(i, m)| (i as u32 + 1, m, Finish::MATTE)));
    imaging.render_stereo(&scene, 1)
}

/// Intensity-weighted centre of the image within `r` pixels of `(u, v)`.
fn centroid(f: &Frame, u: f64, v: f64, r: i64) -> (f64, f64) {
    let (mut s, mut su, mut sv) = (0.0, 0.0, 0.0);
    for y in (v.round() as i64 - r)..=(v.round() as i64 + r) {
        for x in (u.round() as i64 - r)..=(u.round() as i64 + r) {
            let g = f.image[y as usize * f.width + x as usize] as f64;
            s += g;
            su += g * x as f64;
            sv += g * y as f64;
        }
    }
    (su / s, sv / s)
}

/// The `plumb_bob` formula, written out: where the lens puts normalised point `(x, y)`.
fn plumb_bob(d: &mesh::distortion::PlumbBob, x: f64, y: f64) -> (f64, f64) {
    let r2 = x * x + y * y;
    let radial = 1.0 + d.k1 * r2 + d.k2 * r2 * r2 + d.k3 * r2 * r2 * r2;
    (
        x * radial + 2.0 * d.p1 * x * y + d.p2 * (r2 + 2.0 * x * x),
        y * radial + d.p1 * (r2 + 2.0 * y * y) + 2.0 * d.p2 * x * y,
    )
}

const LENS: &str = "distortion = [-0.21, 0.09, 4e-4, -3e-4, 0.01]";

/// Every pixel takes its light from the point of the scene that the formula puts there: the
/// point its virtual pinhole sees at the pixel's source, carried through the formula, lands
/// on the pixel to 0.01 px.
#[test]
fn a_point_lands_where_the_plumb_bob_formula_puts_it() {
    let world = overhead_world("distortion = true", LENS, "");
    let imaging = Imaging::new(&world);
    let d = imaging.rig.left.lens.distortion;
    let mut worst = 0.0f64;
    for v in (0..512).step_by(17) {
        for u in (0..512).step_by(13) {
            let (virt, (sx, sy)) = imaging.light_source(false, u, v).unwrap();
            // The point of the table (1 m below, along the ideal ray) seen there...
            let (x, y) = ((sx - virt.cx) / virt.fx, (sy - virt.cy) / virt.fy);
            // ...put through the formula, in pixels.
            let (xd, yd) = plumb_bob(&d, x, y);
            let (pu, pv) = (1000.0 * xd + 255.5, 1000.0 * yd + 255.5);
            worst = worst.max((pu - u as f64).hypot(pv - v as f64));
        }
    }
    assert!(worst < 0.01, "a pixel's light comes from {worst:.4} px off where the formula puts it");
    // The corner bends by several pixels: the ideal ray of the corner pixel is far from it.
    let (virt, (sx, sy)) = imaging.light_source(false, 0, 0).unwrap();
    let bend = (sx - virt.cx + 255.5).hypot(sy - virt.cy + 255.5);
    assert!(bend > 5.0, "the corner's light comes from {bend:.2} px away");
}

/// End to end through the renderer: a bright square drawn near the corner is seen where the
/// formula puts it. Its expected centre is the formula's image of the square, integrated (the
/// centroid of the warped square, each piece weighed by the area the lens gives it).
#[test]
fn a_square_is_seen_where_the_formula_puts_it() {
    let world = overhead_world("distortion = true", LENS, "");
    let imaging = Imaging::new(&world);
    let d = imaging.rig.left.lens.distortion;
    for (x, y) in [(0.0, 0.0), (0.2, 0.0), (0.19, -0.19), (-0.21, 0.17)] {
        let half = 0.008;
        let (left, _) = draw(&imaging, vec![plate(x, y, 0.0, [half, half], 1.0)]);
        let to_px = |px: f64, py: f64| {
            let (xd, yd) = plumb_bob(&d, px, -py);
            (1000.0 * xd + 255.5, 1000.0 * yd + 255.5)
        };
        let (n, h) = (200, 1e-6);
        let (mut area, mut su, mut sv) = (0.0, 0.0, 0.0);
        for i in 0..n {
            for j in 0..n {
                let (px, py) = (
                    x - half + 2.0 * half * (i as f64 + 0.5) / n as f64,
                    y - half + 2.0 * half * (j as f64 + 0.5) / n as f64,
                );
                let (u, v) = to_px(px, py);
                let ((ux, vx), (uy, vy)) = (to_px(px + h, py), to_px(px, py + h));
                let jacobian = ((ux - u) * (vy - v) - (uy - u) * (vx - v)).abs();
                area += jacobian;
                su += jacobian * u;
                sv += jacobian * v;
            }
        }
        let (eu, ev) = (su / area, sv / area);
        let (cu, cv) = centroid(&left, eu, ev, 14);
        eprintln!("({x}, {y}): warped square's centre ({eu:.3}, {ev:.3}), image ({cu:.3}, {cv:.3})");
        assert!((cu - eu).hypot(cv - ev) < 0.02, "({x}, {y}): seen at ({cu:.3}, {cv:.3}), formula ({eu:.3}, {ev:.3})");
    }
}

/// The variances (px²) of the blur across a vertical step of grey levels `lo` | `hi` between
/// columns `u - 1` and `u`, in row `row`, that fit it: the range of discrete Gaussians whose
/// blurred step, rounded as the image is, gives the row exactly (rounding to whole grey levels
/// drops a kernel's tails, so the profile's second moment would read low); `None` if none does.
fn fitting_variances(f: &Frame, u: usize, row: usize, lo: f64, hi: f64) -> Option<(f64, f64)> {
    let measured: Vec<f64> = (u - 8..u + 8).map(|x| f.image[row * f.width + x] as f64).collect();
    let error = |t: f64| -> f64 {
        let kernel = sim::optics::discrete_gaussian(t as f32);
        let r = kernel.len() as i64 / 2;
        (0..measured.len() as i64)
            .map(|i| {
                // Column u - 8 + i; the step rises at u: blurred, lo + (hi - lo) P(j <= i - 8).
                let below: f64 = (-r..=r).filter(|j| *j <= i - 8).map(|j| kernel[(j + r) as usize] as f64).sum();
                let model = (lo + (hi - lo) * below).round();
                (model - measured[i as usize]).powi(2)
            })
            .sum()
    };
    let ts: Vec<f64> = (1..=3000).map(|k| k as f64 * 0.0005).collect();
    let errors: Vec<f64> = ts.iter().map(|&t| error(t)).collect();
    let fits: Vec<f64> = ts.iter().zip(&errors).filter(|(_, e)| **e == 0.0).map(|(t, _)| *t).collect();
    Some((*fits.first()?, *fits.last()?))
}

#[test]
fn the_blur_at_two_depths_follows_the_thin_lens_circle_of_confusion() {
    let lens = "f_number = 1.4\nfocus_distance_m = 0.85\npsf_sigma_px = 0.5\nfocal_length_mm = 8.0";
    let world = overhead_world("blur = true", lens, "");
    let imaging = Imaging::new(&world);
    // Two steps of albedo, each on a plane of its own: one in focus (depth 0.85 m), one near
    // (0.6 m). Each is a dark half and a bright half meeting at a line along `y`, seen at
    // normalised image coordinate `a` (pixel column 255.5 + 1000 a).
    let step = |a: f64, depth: f64| {
        let (x, half) = (a * depth, [0.02 * depth, 0.05 * depth]);
        vec![plate(x - half[0], 0.0, 1.0 - depth, half, 0.1), plate(x + half[0], 0.0, 1.0 - depth, half, 0.9)]
    };
    let (af, an) = (-0.06, 0.05);
    let mut meshes = step(af, 0.85);
    meshes.extend(step(an, 0.6));
    let (left, _) = draw(&imaging, meshes);
    let lens = imaging.rig.left.lens;
    let pitch = imaging.rig.left.pixel_pitch_mm;
    for (a, depth) in [(af, 0.85), (an, 0.6)] {
        let u = (255.5 + 1000.0 * a).round() as usize;
        let (low, high) = fitting_variances(&left, u, 256, 0.1 * 255.0, 0.9 * 255.0).expect("a Gaussian blur fits");
        // The thin lens by hand: aperture 8 / 1.4 mm, 8 mm focal length, focused at 850 mm,
        // 8 um pixels; a disc of diameter c has a variance of c² / 16 along each axis.
        let (f, z, zf): (f64, f64, f64) = (8.0, depth * 1e3, 850.0);
        let disc = (f / 1.4) * f * (z - zf).abs() / (z * (zf - f)) / 0.008;
        let predicted = 0.5f64.powi(2) + disc * disc / 16.0;
        assert!((lens.circle_of_confusion_px(depth, pitch) - disc).abs() < 1e-9);
        eprintln!("depth {depth}: circle {disc:.2} px, variance {low:.4}-{high:.4} px² fits, predicted {predicted:.4}");
        assert!((low..=high).contains(&predicted), "depth {depth}: {low:.4}-{high:.4} fits, predicted {predicted:.4}");
        assert!(high - low < 0.15 * predicted, "depth {depth}: {low:.4}-{high:.4} px² is too loose a fit to tell");
    }
}

#[test]
fn the_two_cameras_gains_differ_as_the_world_file_says() {
    let sensor = "gain = 1.08\nblack_level_dn = 9.0\ngamma = 1.0\nprnu = 0.0\ndsnu_e = 0.0";
    let world = overhead_world("sensor = true", "", sensor);
    let imaging = Imaging::new(&world);
    let (left_sensor, right_sensor) = (imaging.rig.left.sensor, imaging.rig.right.sensor);
    // Both cameras see one plate of albedo 0.5 under the same light.
    let (l, r) = draw(&imaging, vec![plate(0.05, 0.0, 0.0, [0.4, 0.4], 0.5)]);
    let signal = |f: &Frame, black: f64, gamma: f64| {
        let mean = f.image.iter().map(|&g| g as f64).sum::<f64>() / f.image.len() as f64;
        ((mean - black) / 255.0).powf(1.0 / gamma)
    };
    // The left camera's own response curve undone: each side's signal before its gain.
    let left = signal(&l, left_sensor.black_level_dn, 1.0);
    let right = signal(&r, right_sensor.black_level_dn, 1.0);
    assert_eq!(right_sensor.gain, 1.08);
    let left_expected =
        left_sensor.gain * (0.5 * left_sensor.white_e / left_sensor.full_well_e).powf(left_sensor.gamma);
    assert!((left / left_expected - 1.0).abs() < 0.01, "left {left} vs {left_expected}");
    let ratio = right / (0.5 * right_sensor.white_e / right_sensor.full_well_e);
    assert!((ratio / 1.08 - 1.0).abs() < 0.005, "the right camera's gain measured {ratio:.4}, the file says 1.08");
}

fn v(p: &Point3<f64>) -> Vector {
    Vector::new(p.x as f32, p.y as f32, p.z as f32)
}

#[test]
fn depth_and_id_maps_are_the_true_distorted_cameras() {
    let scn = Scenario::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/widgets.toml")).unwrap();
    let scene = Scene::settle(&scn, 3);
    let imaging = Imaging::new(&scn.world);
    assert!(imaging.effects.distortion && imaging.effects.mounting);
    let meshes: Vec<(u32, ParryMesh)> = scene
        .world_meshes(&scn.library)
        .map(|(id, m)| (id, ParryMesh::new(m.vertices.iter().map(v).collect(), m.triangles.clone()).unwrap()))
        .collect();
    let (l, r) = imaging.render_stereo(&scene.render_scene(&scn.library, &imaging), 3);
    let mut rng = StdRng::seed_from_u64(5);
    let (mut compared, mut agree_ids, mut worst) = (0, 0, 0.0f64);
    for (frame, built) in [(&l, &imaging.rig.left), (&r, &imaging.rig.right)] {
        let cam = built.lens_camera();
        let axis = cam.pinhole.world_from_cam.rotation * Vector3::z();
        for _ in 0..1000 {
            let (x, y) = (rng.random_range(0..frame.width), rng.random_range(0..frame.height));
            let (o, d) = cam.ray_world(x as f64, y as f64);
            let ray = Ray::new(v(&o), v(&Point3::from(d)));
            let hit = meshes
                .iter()
                .filter_map(|(id, m)| m.cast_ray(&Pose::IDENTITY, &ray, 10.0, true).map(|t| (t, *id)))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let Some((t, id)) = hit else { continue };
            let cast = t as f64 * d.dot(&axis);
            let rendered = frame.depth[y * frame.width + x] as f64;
            compared += 1;
            // Beside an outline the nearest virtual pixel may show the other surface.
            if (rendered - cast).abs() <= 5e-4 {
                agree_ids += usize::from(frame.ids[y * frame.width + x] as u32 == id);
            }
            worst = worst.max((rendered - cast).abs().min(1.0));
        }
    }
    let agreeing = agree_ids as f64 / compared as f64;
    eprintln!("{compared} pixels: depth and id agree with ray casts through the true lens at {agreeing:.4}");
    assert!(agreeing >= 0.99, "depth and id agree at only {agreeing:.4} of {compared} pixels");
}
