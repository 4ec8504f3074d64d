//! Canny's sub-pixel acuity on rendered images: straight edges of a plate, rendered by the
//! simulator at known sub-pixel positions (with and without sensor noise), against the edge
//! lines projected through the camera.

use mesh::{PinholeCamera, TriMesh};
use nalgebra::{Isometry3, Point2, Point3, Translation3, UnitQuaternion, Vector3};
use sim::render::{Light, RenderScene, render};
use vision::{CannyParams, GreyImage, canny};

fn overhead() -> PinholeCamera {
    PinholeCamera::looking_at(
        (512, 512),
        1000.0,
        [255.5, 255.5],
        Point3::new(0.0, 0.0, 1.0),
        Point3::origin(),
        Vector3::y(),
    )
}

/// Distance of `p` from the segment `a`-`b`, and how far along it `p` falls (0-1).
fn to_segment(p: Point2<f64>, a: Point2<f64>, b: Point2<f64>) -> (f64, f64) {
    let ab = b - a;
    let t = (p - a).dot(&ab) / ab.norm_squared();
    let foot = a + ab * t.clamp(0.0, 1.0);
    ((p - foot).norm(), t)
}

/// RMS distance from the projected plate outline of the edgels found along it.
fn rms_for(angle_deg: f64, shift_px: (f64, f64), noise: f64) -> (f64, usize) {
    let cam = overhead();
    let (hx, hy, top) = (0.09, 0.06, 0.01);
    // A shift of one pixel at the plate's top (0.99 m from the camera) is 0.99 mm.
    let px_m = (1.0 - top) / cam.fx;
    let pose = Isometry3::from_parts(
        Translation3::new(shift_px.0 * px_m, -shift_px.1 * px_m, top / 2.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, angle_deg.to_radians()),
    );
    let plate = TriMesh::cuboid(Vector3::new(hx, hy, top / 2.0), 0.85).transformed(&pose);
    let table =
        TriMesh::cuboid(Vector3::new(1.0, 1.0, 0.05), 0.3).transformed(&Isometry3::translation(0.0, 0.0, -0.05));
    let light = Light { towards_light: Vector3::new(0.2, -0.3, 1.0).normalize(), diffuse: 0.7, ambient: 0.3 };
    let frame = render(&RenderScene::new([(0, table), (1, plate)], &light), &cam, noise, 9);
    let img = GreyImage::new(frame.width, frame.height, frame.image).unwrap();
    let corners: Vec<Point2<f64>> = [(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy)]
        .iter()
        .map(|&(x, y)| cam.project_world(&(pose * Point3::new(x, y, top / 2.0))).unwrap())
        .collect();
    let map = canny(&img, &CannyParams::default());
    let mut sq = Vec::new();
    for e in &map.edgels {
        let p = Point2::new(e.x as f64, e.y as f64);
        let nearest =
            (0..4).map(|k| to_segment(p, corners[k], corners[(k + 1) % 4])).min_by(|a, b| a.0.total_cmp(&b.0)).unwrap();
        let side = (corners[1] - corners[0]).norm().min((corners[2] - corners[1]).norm());
        let away_from_corners = nearest.1 * side > 6.0 && (1.0 - nearest.1) * side > 6.0;
        if nearest.0 < 2.0 && away_from_corners {
            sq.push(nearest.0 * nearest.0);
        }
    }
    ((sq.iter().sum::<f64>() / sq.len() as f64).sqrt(), sq.len())
}

#[test]
fn rendered_straight_edges_are_located_within_a_tenth_of_a_pixel_rms() {
    for noise in [0.0, 1.5] {
        for (angle, shift) in [
            (0.0, (0.0, 0.0)),
            (0.0, (0.25, 0.6)),
            (7.0, (0.4, 0.1)),
            (30.0, (0.13, 0.77)),
            (45.0, (0.5, 0.5)),
            (62.0, (0.9, 0.3)),
        ] {
            let (rms, n) = rms_for(angle, shift, noise);
            eprintln!("noise {noise}, angle {angle} deg, shift {shift:?}: rms {rms:.4} px over {n} edgels");
            assert!(n > 400, "only {n} edgels along the outline");
            assert!(rms <= 0.1, "noise {noise}, angle {angle}: rms {rms:.3} px");
        }
    }
}
