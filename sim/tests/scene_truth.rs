//! The settled scene and the rendered images, checked against independent computations:
//! parry ray casts and contact queries, and the models' own geometry projected through the
//! exported calibration.

use mesh::PinholeCamera;
use nalgebra::{Point2, Point3, Vector2};
use parry3d::math::{Pose, Vector};
use parry3d::query::{Ray, RayCast};
use parry3d::shape::TriMesh as ParryMesh;
use rand::{RngExt, SeedableRng, rngs::StdRng};
use sim::render::{Frame, Light, RenderScene, render, render_stereo};
use sim::{Scenario, Scene};
use std::path::Path;

fn widgets() -> Scenario {
    Scenario::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/widgets.toml")).unwrap()
}

fn shade(scn: &Scenario, scene: &Scene) -> RenderScene {
    RenderScene::new(scene.world_meshes(&scn.library), &Light::from(&scn.world.light))
}

fn v(p: &Point3<f64>) -> Vector {
    Vector::new(p.x as f32, p.y as f32, p.z as f32)
}

#[test]
fn settled_objects_rest_on_the_table_without_interpenetrating() {
    let scn = widgets();
    let table = scn.world.table.size_m;
    for seed in [1, 2, 3] {
        let scene = Scene::settle(&scn, seed);
        assert!(scene.settle.at_rest, "seed {seed}: not at rest: {:?}", scene.settle);
        let shapes: Vec<_> = scene
            .objects
            .iter()
            .map(|o| {
                let shape = sim::physics::collision_shape(&scn.library.models[&o.model]);
                (shape, sim::convert::pose(&o.world_from_model))
            })
            .collect();
        for o in &scene.objects {
            let mesh = scn.library.models[&o.model].mesh.transformed(&o.world_from_model);
            let (lo, hi) = mesh.bounds().unwrap();
            assert!(lo.z >= -1e-3, "seed {seed}: {} sinks {:.2} mm into the table", o.model, -lo.z * 1e3);
            assert!(lo.z <= 0.12, "seed {seed}: {} floats at {:.3} m", o.model, lo.z);
            assert!(lo.x > -table[0] / 2.0 && hi.x < table[0] / 2.0, "seed {seed}: {} is off the table", o.model);
            assert!(lo.y > -table[1] / 2.0 && hi.y < table[1] / 2.0, "seed {seed}: {} is off the table", o.model);
        }
        for i in 0..shapes.len() {
            for j in i + 1..shapes.len() {
                let ((a, pa), (b, pb)) = (&shapes[i], &shapes[j]);
                if let Some(c) = parry3d::query::contact(pa, a.as_ref(), pb, b.as_ref(), 0.0).unwrap() {
                    assert!(
                        c.dist >= -1e-3,
                        "seed {seed}: {} and {} interpenetrate by {:.2} mm",
                        scene.objects[i].model,
                        scene.objects[j].model,
                        -c.dist * 1e3
                    );
                }
            }
        }
    }
}

#[test]
fn the_same_seed_gives_identical_images_and_another_seed_does_not() {
    let scn = widgets();
    let calib = sim::rig::calibration(&scn.world.cameras);
    let pair = |seed| {
        let scene = Scene::settle(&scn, seed);
        render_stereo(&shade(&scn, &scene), &calib, scn.world.render.noise_sigma, seed)
    };
    let (a, b, c) = (pair(5), pair(5), pair(6));
    assert!(a == b, "seed 5 rendered twice differs");
    assert!(a.0.image != c.0.image, "seeds 5 and 6 gave the same left image");
}

/// Depth along the optical axis of the nearest surface on the ray through pixel `(u, v)`.
fn ray_cast_depth(meshes: &[ParryMesh], cam: &PinholeCamera, u: f64, v_: f64) -> Option<f64> {
    let (origin, dir) = cam.ray_world(u, v_);
    let ray = Ray::new(v(&origin), v(&dir.into()));
    let t = meshes.iter().filter_map(|m| m.cast_ray(&Pose::IDENTITY, &ray, 10.0, true)).fold(f32::MAX, f32::min);
    let axis = cam.world_from_cam.rotation * nalgebra::Vector3::z();
    (t < f32::MAX).then(|| t as f64 * dir.dot(&axis))
}

#[test]
fn depth_maps_agree_with_parry_ray_casts() {
    let scn = widgets();
    let scene = Scene::settle(&scn, 1);
    let meshes: Vec<ParryMesh> = scene
        .world_meshes(&scn.library)
        .map(|(_, m)| ParryMesh::new(m.vertices.iter().map(v).collect(), m.triangles.clone()).unwrap())
        .collect();
    let calib = sim::rig::calibration(&scn.world.cameras);
    let rs = shade(&scn, &scene);
    let mut rng = StdRng::seed_from_u64(11);
    let (mut on_objects, mut worst) = (0, 0.0f64);
    for cam in [&calib.left, &calib.right] {
        let frame = render(&rs, cam, 0.0, 0);
        for _ in 0..1500 {
            let (x, y) = (rng.random_range(0..frame.width), rng.random_range(0..frame.height));
            let rendered = frame.depth[y * frame.width + x] as f64;
            let cast = ray_cast_depth(&meshes, cam, x as f64, y as f64).unwrap_or(0.0);
            assert!(
                (rendered - cast).abs() <= 5e-4,
                "pixel ({x}, {y}): depth map {rendered:.5} m, ray cast {cast:.5} m"
            );
            on_objects += usize::from(frame.ids[y * frame.width + x] > 0);
            worst = worst.max((rendered - cast).abs());
        }
    }
    eprintln!("depth vs ray cast over 3000 pixels: worst {:.4} mm", worst * 1e3);
    assert!(on_objects > 50, "only {on_objects} samples fell on objects");
}

fn bilinear(f: &Frame, p: Point2<f64>) -> Option<f64> {
    let (x0, y0) = (p.x.floor(), p.y.floor());
    if x0 < 0.0 || y0 < 0.0 || x0 + 1.0 >= f.width as f64 || y0 + 1.0 >= f.height as f64 {
        return None;
    }
    let (fx, fy) = (p.x - x0, p.y - y0);
    let at = |dx: usize, dy: usize| f.image[(y0 as usize + dy) * f.width + x0 as usize + dx] as f64;
    Some(
        at(0, 0) * (1.0 - fx) * (1.0 - fy)
            + at(1, 0) * fx * (1.0 - fy)
            + at(0, 1) * (1.0 - fx) * fy
            + at(1, 1) * fx * fy,
    )
}

fn nearest<T: Copy>(f: &Frame, data: &[T], p: Point2<f64>) -> Option<T> {
    let (x, y) = (p.x.round(), p.y.round());
    let inside = x >= 0.0 && y >= 0.0 && (x as usize) < f.width && (y as usize) < f.height;
    inside.then(|| data[y as usize * f.width + x as usize])
}

/// Where the intensity step across the projected edge at `q` (unit normal `n`) actually is,
/// as a signed offset along `n`; `None` where the image has no clean step there.
fn measured_step(f: &Frame, q: Point2<f64>, n: Vector2<f64>) -> Option<f64> {
    let profile: Vec<(f64, f64)> =
        (-16..=16).map(|k| k as f64 / 4.0).map(|s| Some((s, bilinear(f, q + n * s)?))).collect::<Option<_>>()?;
    let side = |range: std::ops::RangeInclusive<f64>| -> Vec<f64> {
        profile.iter().filter(|(s, _)| range.contains(s)).map(|(_, i)| *i).collect()
    };
    let (lo, hi) = (side(-4.0..=-2.5), side(2.5..=4.0));
    let spread = |xs: &[f64]| xs.iter().cloned().fold(f64::MIN, f64::max) - xs.iter().cloned().fold(f64::MAX, f64::min);
    let mean = |xs: &[f64]| xs.iter().sum::<f64>() / xs.len() as f64;
    let (l, r) = (mean(&lo), mean(&hi));
    if spread(&lo) > 3.0 || spread(&hi) > 3.0 || (l - r).abs() < 20.0 {
        return None;
    }
    let mid = (l + r) / 2.0;
    let inner: Vec<&(f64, f64)> = profile.iter().filter(|(s, _)| s.abs() <= 2.5).collect();
    let crossings: Vec<f64> = inner
        .windows(2)
        .filter(|w| (w[0].1 - mid) * (w[1].1 - mid) <= 0.0 && w[0].1 != w[1].1)
        .map(|w| w[0].0 + (mid - w[0].1) / (w[1].1 - w[0].1) * (w[1].0 - w[0].0))
        .collect();
    (crossings.len() == 1).then(|| crossings[0])
}

/// The projected edge point is a visible boundary of its own object: no other object near it,
/// and the depth just beside it on one side is its own.
fn visible(f: &Frame, id: u16, q: Point2<f64>, n: Vector2<f64>, depth: f64) -> bool {
    let ids: Option<Vec<u16>> = (-4..=4).map(|s| nearest(f, &f.ids, q + n * s as f64)).collect();
    let Some(ids) = ids else { return false };
    if ids.iter().any(|&i| i != 0 && i != id) {
        return false;
    }
    [-1.5, 1.5].iter().any(|&s| {
        let p = q + n * s;
        nearest(f, &f.ids, p) == Some(id) && nearest(f, &f.depth, p).is_some_and(|d| (d as f64 - depth).abs() < 3e-3)
    })
}

#[derive(Default)]
struct EdgeErrors {
    points: Vec<f64>,
    vertices: Vec<f64>,
}

/// A measured image line near a wireframe vertex: (vertex, a point on the line, direction).
type LineAt = (Point3<f64>, Point2<f64>, Vector2<f64>);

/// Feature edges of every object projected through `cam`, against the steps found in `frame`.
fn edge_errors(scn: &Scenario, scene: &Scene, cam: &PinholeCamera, frame: &Frame, out: &mut EdgeErrors) {
    for o in &scene.objects {
        let model = &scn.library.models[&o.model];
        let mut lines_at: Vec<LineAt> = Vec::new();
        let projected: Vec<Option<(Point2<f64>, Point2<f64>)>> = model
            .wireframe
            .iter()
            .map(|s| {
                Some((cam.project_world(&(o.world_from_model * s.a))?, cam.project_world(&(o.world_from_model * s.b))?))
            })
            .collect();
        for (si, seg) in model.wireframe.iter().enumerate() {
            let (a, b) = (o.world_from_model * seg.a, o.world_from_model * seg.b);
            let Some((pa, pb)) = projected[si] else {
                continue;
            };
            let length_px = (pb - pa).norm();
            if length_px < 16.0 {
                continue;
            }
            let d = (pb - pa) / length_px;
            let n = Vector2::new(-d.y, d.x);
            let mut found: Vec<Point2<f64>> = Vec::new();
            let steps = (length_px / 2.0) as usize;
            for k in 0..=steps {
                let t = k as f64 / steps as f64;
                if t * length_px < 5.0 || (1.0 - t) * length_px < 5.0 {
                    continue; // corners: other edges meet there
                }
                let p3 = a + (b - a) * t;
                let q = cam.project_world(&p3).unwrap();
                // The profile spans 4 px each side: another edge that close would blend in.
                let crowded = projected
                    .iter()
                    .enumerate()
                    .any(|(sj, other)| sj != si && other.is_some_and(|(c, d)| distance_to_segment(q, c, d) < 4.5));
                if crowded {
                    continue;
                }
                let depth = cam.world_from_cam.inverse_transform_point(&p3).z;
                if !visible(frame, o.id as u16, q, n, depth) {
                    continue;
                }
                if let Some(s) = measured_step(frame, q, n) {
                    out.points.push(s.abs());
                    found.push(q + n * s);
                }
            }
            if found.len() >= 8 {
                let (c, dir) = fit_line(&found);
                lines_at.push((a, c, dir));
                lines_at.push((b, c, dir));
            }
        }
        // A vertex where two measured edges meet at 45 deg or more: where their lines cross.
        // (Shallower crossings magnify the lines' own fitting error, not the renderer's.)
        for (i, (v1, c1, d1)) in lines_at.iter().enumerate() {
            for (v2, c2, d2) in &lines_at[i + 1..] {
                if (v1 - v2).norm() > 1e-9 || d1.perp(d2).abs() < std::f64::consts::FRAC_1_SQRT_2 {
                    continue;
                }
                let t = (c2 - c1).perp(d2) / d1.perp(d2);
                let crossing = c1 + d1 * t;
                out.vertices.push((crossing - cam.project_world(v1).unwrap()).norm());
            }
        }
    }
}

fn distance_to_segment(p: Point2<f64>, a: Point2<f64>, b: Point2<f64>) -> f64 {
    let ab = b - a;
    let t = ((p - a).dot(&ab) / ab.norm_squared().max(1e-12)).clamp(0.0, 1.0);
    (p - (a + ab * t)).norm()
}

/// Orthogonal-regression line through points: (centroid, unit direction).
fn fit_line(pts: &[Point2<f64>]) -> (Point2<f64>, Vector2<f64>) {
    let c = pts.iter().fold(Vector2::zeros(), |s, p| s + p.coords) / pts.len() as f64;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in pts {
        let d = p.coords - c;
        sxx += d.x * d.x;
        sxy += d.x * d.y;
        syy += d.y * d.y;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    (Point2::from(c), Vector2::new(angle.cos(), angle.sin()))
}

#[test]
fn projected_feature_edges_land_on_the_rendered_intensity_edges() {
    let scn = widgets();
    let calib = sim::rig::calibration(&scn.world.cameras);
    let mut errors = EdgeErrors::default();
    for seed in [1, 2] {
        let scene = Scene::settle(&scn, seed);
        let rs = shade(&scn, &scene);
        for cam in [&calib.left, &calib.right] {
            let frame = render(&rs, cam, 0.0, 0);
            edge_errors(&scn, &scene, cam, &frame, &mut errors);
        }
    }
    let stats = |xs: &mut Vec<f64>| {
        xs.sort_by(f64::total_cmp);
        (xs.len(), xs[xs.len() / 2], xs[xs.len() - 1])
    };
    let (n, median, worst) = stats(&mut errors.points);
    eprintln!("edge points: {n}, median {median:.3} px, worst {worst:.3} px");
    assert!(n >= 300, "only {n} edge points could be measured");
    assert!(worst <= 0.5, "an edge point lies {worst:.3} px from its intensity edge");
    let (n, median, worst) = stats(&mut errors.vertices);
    eprintln!("vertices: {n}, median {median:.3} px, worst {worst:.3} px");
    assert!(n >= 10, "only {n} vertices could be measured");
    assert!(worst <= 0.5, "a vertex lies {worst:.3} px from where its intensity edges meet");
}
