//! The `ideal` preset reproduces the renderer as it was before the realistic cell (commit
//! 82a7054) bit for bit: every shipped world's stereo pair at its own seed (images, depth and
//! id maps), drawn through [`sim::imaging::Imaging`] from its ideal copy (`worlds/ideal/`), hashes to what
//! that renderer gave (the hashes below were printed by this test run on 82a7054), so every
//! earlier figure can still be reproduced.

use sim::imaging::Imaging;
use sim::realism::Preset;
use sim::render::Frame;
use sim::{Scenario, Scene};
use std::path::Path;

/// FNV-1a over the bytes: written here so the hashes do not depend on any crate's version.
fn fnv1a(h: &mut u64, bytes: &[u8]) {
    for &b in bytes {
        *h ^= b as u64;
        *h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
}

fn frame_hash(f: &Frame) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325;
    fnv1a(&mut h, &f.image);
    f.depth.iter().for_each(|d| fnv1a(&mut h, &d.to_le_bytes()));
    f.ids.iter().for_each(|i| fnv1a(&mut h, &i.to_le_bytes()));
    h
}

const BEFORE: [(&str, u64, u64); 4] = [
    ("widgets", 0xa35ef78f272ac6e9, 0x3219d5d234dc8b77),
    ("dense", 0xafe9c3f6d8cf763d, 0xeee7c7d91c1f3852),
    ("side_light", 0x49a102a21f0221e9, 0x7023f2708daaf7de),
    ("two_objects", 0x8a45055d804e9843, 0xa2c7943f39ebf139),
];

#[test]
fn ideal_renders_hash_as_before() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds");
    for (name, left, right) in BEFORE {
        let scn = Scenario::load(&dir.join(format!("ideal/{name}.toml"))).unwrap();
        assert_eq!(scn.world.realism, Preset::Ideal);
        let scene = Scene::settle(&scn, scn.world.seed);
        let imaging = Imaging::new(&scn.world);
        let (l, r) = imaging.render_stereo(&scene.render_scene(&scn.library, &imaging), scn.world.seed);
        assert_eq!((frame_hash(&l), frame_hash(&r)), (left, right), "{name}: the ideal pair differs from before");
    }
}

#[test]
fn the_realistic_preset_differs_from_the_ideal() {
    let scn = Scenario::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/widgets.toml")).unwrap();
    let scene = Scene::settle(&scn, scn.world.seed);
    let imaging = Imaging::new(&scn.world);
    let (l, _) = imaging.render_stereo(&scene.render_scene(&scn.library, &imaging), scn.world.seed);
    assert_ne!(frame_hash(&l), BEFORE[0].1);
}
