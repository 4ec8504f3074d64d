//! Tests of the image checks, beside them (kept apart to keep `verify.rs` readable).

use super::*;
use crate::front_end::canny::Edgel;

/// A block half behind another shows edgels only where it is in view: counted over its
/// whole camera-facing wireframe its image support falls well short, counted over the part
/// the other leaves in view it is whole.
#[test]
fn a_part_half_hidden_is_judged_on_what_is_in_view() {
    use crate::matcher::occlusion::Solid;
    use nalgebra::{Point3, Translation3, UnitQuaternion};
    let model = crate::matcher::fixtures::model("block");
    let cam = crate::matcher::fixtures::camera_at(Point3::new(0.0, -0.6, 0.6));
    let place = |x: f64, y: f64, z: f64, yaw: f64| {
        cam.cam_from_world()
            * Isometry3::from_parts(Translation3::new(x, y, z), UnitQuaternion::from_euler_angles(0.0, 0.0, yaw))
    };
    let (pose, front) = (place(0.0, 0.0, 0.015, 0.4), place(-0.03, -0.07, 0.07, 0.0));
    let occluder = Solid::new(&model, &front);
    let (all_edges, _) = drawn::model_edges(&model, &pose, &cam);
    // What the camera sees of the block behind: its edgels where the one in front does not
    // hide the block's surface (taken at the block's own depth along each pixel's ray).
    let depth = (pose * model.bounding_sphere().0).z;
    let mut edges = EdgeMap::new(512, 512);
    for (e, &pixel) in all_edges.edgels.iter().zip(&all_edges.pixel) {
        let ray = cam.ray_cam(e.x as f64, e.y as f64);
        if !occluder.hides(&Point3::from(ray * (depth / ray.z))) {
            edges.push(pixel as usize, *e);
        }
    }
    assert!(edges.edgels.len() * 10 < all_edges.edgels.len() * 8, "the block in front hides too little");
    let ev = ImageEvidence::new(&cam, &edges, Vec::new());
    let own = Solid::new(&model, &pose);
    let plain = image_support(&model, &pose, &ev);
    let (in_view, share) = image_support_unhidden(&model, &pose, &ev, &[&occluder, &own]);
    assert!(plain < 0.8, "counted over the whole wireframe: {plain:.2}");
    assert!(in_view > 0.9, "counted over the part in view: {in_view:.2}");
    assert!(share > 0.2 && share < 0.8, "{share:.2} of the wireframe in view");
}

/// The mask only spares work: wherever the exact search finds an edgel along a direction,
/// the mask says there may be one (tried on random edgels, points and directions); and it
/// holds exactly the pixels with an edgel.
#[test]
fn the_mask_never_rules_out_what_the_exact_search_finds() {
    let mut state = 12345u64;
    let mut next = move || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut edges = EdgeMap::new(64, 64);
    for _ in 0..600 {
        let (px, py) = ((next() * 64.0) as usize, (next() * 64.0) as usize);
        if edges.edgel_at(px, py).is_none() {
            let (x, y) = (px as f64 + next() - 0.5, py as f64 + next() - 0.5);
            let orientation = (next() * 4.0 - 2.0) * std::f64::consts::PI;
            edges.push(
                py * 64 + px,
                Edgel { x: x as f32, y: y as f32, orientation: orientation as f32, contrast: 9.0, sides: [0.0; 2] },
            );
        }
    }
    let mask = EdgeMask::of(&edges);
    for (pixel, &i) in edges.at_pixel.iter().enumerate() {
        assert_eq!(mask.occupied(pixel), i != crate::front_end::canny::NO_EDGEL, "pixel {pixel}");
    }
    let (mut found, mut spared) = (0, 0);
    for _ in 0..20000 {
        let (x, y) = (next() * 66.0 - 1.0, next() * 66.0 - 1.0);
        let angle = next() * std::f64::consts::TAU;
        let dir = Vector2::new(angle.cos(), angle.sin());
        let near = mask.any_near(x, y, EdgeMask::bins_along(dir));
        let along = edgel_along(&edges, &mask, x, y, dir);
        assert_eq!(along, edgel_near(&edges, &mask, x, y, dir).is_some(), "the scans differ at ({x:.2}, {y:.2})");
        if along {
            found += 1;
            assert!(near, "the mask ruled out an edgel along {dir:?} near ({x:.2}, {y:.2})");
        } else if !near {
            spared += 1;
        }
    }
    // Both outcomes happen, so the test says something.
    assert!(found > 1000 && spared > 1000, "found {found}, spared {spared}");
}

/// The rough arctangent stays within its bound of the library's, all round the circle
/// (the axes and diagonals too), so the mask's bins hold every edge the exact test takes.
#[test]
fn the_rough_arctangent_stays_within_its_bound() {
    let mut worst: f64 = 0.0;
    for k in 0..100_000 {
        let angle = (k as f64 / 100_000.0 - 0.5) * std::f64::consts::TAU;
        for r in [1e-3, 1.0, 7.0] {
            let (y, x) = (r * angle.sin(), r * angle.cos());
            let off = (rough_atan2(y, x) - y.atan2(x)).abs();
            // Either side of the cut at pi the two may name one angle by +-pi.
            worst = worst.max(off.min((off - std::f64::consts::TAU).abs()));
        }
    }
    for (y, x) in [(0.0, 1.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 0.0), (1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)] {
        assert!((rough_atan2(y, x) - f64::atan2(y, x)).abs() < 1e-12, "({y}, {x})");
    }
    assert!(worst < 0.0016, "off by {worst} rad");
    assert!(worst < ROUGH_ATAN2_RAD);
}

/// The nearest-first scan looks at every pixel of the square once, nearer ones first.
#[test]
fn the_nearest_first_scan_covers_the_square_once_in_order_of_distance() {
    let r = SCAN_PX as i8;
    let mut all: Vec<(i8, i8)> = NEAREST_FIRST.to_vec();
    let distance = |&(dx, dy): &(i8, i8)| i32::from(dx) * i32::from(dx) + i32::from(dy) * i32::from(dy);
    assert!(NEAREST_FIRST.windows(2).all(|w| distance(&w[0]) <= distance(&w[1])));
    all.sort();
    all.dedup();
    let square: Vec<(i8, i8)> = (-r..=r).flat_map(|dx| (-r..=r).map(move |dy| (dx, dy))).collect();
    assert_eq!(all, square);
}

/// An L-bracket read into a U-channel's corner runs along the channel's edges for most of
/// its length; a block standing apart runs along none of them.
#[test]
fn a_part_read_into_a_located_ones_edges_is_explained_by_it() {
    use nalgebra::{Point3, Translation3};
    let (channel, bracket, block) = (
        crate::matcher::fixtures::model("u_channel"),
        crate::matcher::fixtures::model("l_bracket"),
        crate::matcher::fixtures::model("block"),
    );
    let cam = crate::matcher::fixtures::camera_at(Point3::new(0.0, -0.6, 0.6));
    let place = |x: f64, y: f64| {
        cam.cam_from_world() * Isometry3::from_parts(Translation3::new(x, y, 0.0125), Default::default())
    };
    let channel_pose = place(0.0, 0.0);
    let explained = Explained::of([(&channel, &channel_pose)], &cam);
    // Moved 5 mm along -x, the bracket's long arm lies in the channel's base and its short
    // arm is the channel's left arm.
    assert!(explained.share(&bracket, &place(-0.005, 0.0), &cam) > 0.6);
    assert_eq!(explained.share(&block, &place(0.15, 0.1), &cam), 0.0);
    assert_eq!(explained.share(&channel, &channel_pose, &cam), 1.0);
}

/// What the image shows of a channel beyond a bracket read into its corner: its third arm,
/// along edgels where the channel was drawn, along none in an empty image, and nothing at all
/// where another report's edges account for every edgel there (they say nothing of the
/// channel).
#[test]
fn a_larger_model_beyond_a_smaller_one_is_judged_off_the_other_reports_edges() {
    use nalgebra::{Point3, Translation3};
    let (channel, bracket) =
        (crate::matcher::fixtures::model("u_channel"), crate::matcher::fixtures::model("l_bracket"));
    let cam = crate::matcher::fixtures::camera_at(Point3::new(0.0, -0.6, 0.6));
    let place =
        |x: f64| cam.cam_from_world() * Isometry3::from_parts(Translation3::new(x, 0.0, 0.0125), Default::default());
    let (channel_pose, bracket_pose) = (place(0.0), place(-0.005));
    let nothing = Explained::of([], &cam);
    let beyond = |edges: &EdgeMap, explained: &Explained| {
        let ev = ImageEvidence::new(&cam, edges, Vec::new());
        image_support_beyond((&channel, &channel_pose), (&bracket, &bracket_pose), &ev, &[], explained, 3.0, &|_| false)
    };
    let (drawn, _) = drawn::model_edges(&channel, &channel_pose, &cam);
    let Beyond { share, px, kept_from_view_px, .. } = beyond(&drawn, &nothing);
    assert!(share > 0.9 && px > 20.0, "the channel drawn: {share:.2} of {px:.0} px");
    assert_eq!(kept_from_view_px, 0.0, "nothing hides it and it is all in the image");
    let Beyond { share, px, .. } = beyond(&EdgeMap::new(512, 512), &nothing);
    assert!(share == 0.0 && px > 20.0, "an empty image: {share:.2} of {px:.0} px");
    let another = Explained::of([(&channel, &channel_pose)], &cam);
    let Beyond { share, px, .. } = beyond(&drawn, &another);
    assert_eq!((share, px), (0.0, 0.0), "all of it another report's edges");
    // The same image cropped to its left half: the channel lies across its right border, and
    // what falls outside is kept from view, not counted as unseen.
    let (full, _) = drawn::model_edges(&channel, &channel_pose, &cam);
    let cut_at = cam.project_cam(&(channel_pose * Point3::new(0.0, 0.0, 0.0))).unwrap().x.floor() as usize;
    let mut cropped = EdgeMap::new(cut_at, 512);
    for (i, e) in full.edgels.iter().enumerate() {
        let (x, y) = full.pixel_of(i as u32);
        if x < cut_at {
            cropped.push(y * cut_at + x, *e);
        }
    }
    let whole = beyond(&drawn, &nothing);
    let cut = beyond(&cropped, &nothing);
    assert!(cut.kept_from_view_px > 20.0, "the right half out of view: {cut:?}");
    assert!(
        (cut.px + cut.kept_from_view_px - whole.px).abs() < 1e-9,
        "all of it looked at or out of view: {cut:?} {whole:?}"
    );
    assert!(cut.px == 0.0 || cut.share > 0.9, "what is in view is drawn: {cut:?}");
}

/// The share of an image line along located edges, from the edges near its box, is the
/// share every edge gives sample by sample: random short edges and lines over a small image,
/// many of them near and along each other.
#[test]
fn a_lines_share_from_the_edges_near_it_is_the_share_from_all_of_them() {
    let mut rng = crate::matcher::fixtures::Lcg(7);
    let mut point = || Point2::new(100.0 + 60.0 * rng.next(), 100.0 + 60.0 * rng.next());
    let segments: Vec<(Point2<f64>, Point2<f64>, Vector2<f64>)> = (0..60)
        .map(|_| {
            let (a, b) = (point(), point());
            (a, b, (b - a).normalize())
        })
        .collect();
    let explained = Explained { segments };
    let (mut some, mut none) = (0, 0);
    for k in 0..400 {
        let a = point();
        // Every other line runs along an edge, a pixel aside.
        let b = if k % 2 == 0 {
            let (ea, eb, _) = explained.segments[k % 60];
            a + (eb - ea)
        } else {
            point()
        };
        let line = ImageLine { a, b, normal: nalgebra::Vector3::z() };
        let len = (b - a).norm();
        if len < 2.0 * STEP_PX {
            continue;
        }
        let (steps, dir) = ((len / STEP_PX) as usize, (b - a) / len);
        let every =
            (1..steps).filter(|&s| explained.explains(&(a + (b - a) * (s as f64 / steps as f64)), &dir)).count();
        let share = every as f64 / (steps - 1) as f64;
        assert_eq!(explained.share_of_line(&line), share, "line {k}");
        if share > 0.0 { some += 1 } else { none += 1 }
    }
    assert!(some > 50 && none > 50, "{some} lines partly explained, {none} not");
}
