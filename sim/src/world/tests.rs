//! World files: what is read, and how each fault is named (file, line, field).
use super::*;

const GOOD: &str = r#"
seed = 3
[table]
size_m = [1.0, 1.0]
height_m = 0.7
albedo = 0.3
[cameras.left]
focal_px = 900.0
position_m = [-0.1, -0.7, 0.6]
look_at_m = [0.0, 0.0, 0.0]
[cameras.right]
focal_px = 900.0
position_m = [0.1, -0.7, 0.6]
look_at_m = [0.0, 0.0, 0.0]
[[objects]]
model = "block"
position_m = [0.0, 0.0, 0.015]
"#;

fn error_of(text: &str) -> (usize, String, String) {
    match WorldFile::parse(text, "w.toml") {
        Err(WorldError::Invalid { line, field, message, .. }) => (line, field, message),
        other => panic!("expected an invalid-world error, got {other:?}"),
    }
}

#[test]
fn a_good_file_parses_with_defaults() {
    let w = WorldFile::parse(GOOD, "w.toml").unwrap();
    assert_eq!(w.seed, 3);
    assert_eq!(w.cameras.left.resolution, [512, 512]);
    assert_eq!(w.render.noise_sigma, 1.5);
}

#[test]
fn a_wrong_type_names_its_line_and_field() {
    let bad = GOOD.replace("focal_px = 900.0\nposition_m = [0.1", "focal_px = \"wide\"\nposition_m = [0.1");
    let (line, field, message) = error_of(&bad);
    assert_eq!(line, 12);
    assert_eq!(field, "cameras.right.focal_px");
    assert!(message.contains("expected f64"), "{message}");
}

#[test]
fn an_unknown_field_is_named() {
    let bad = GOOD.replace("albedo = 0.3", "albedo = 0.3\ncolour = 2");
    let (line, field, message) = error_of(&bad);
    assert_eq!(line, 7);
    assert_eq!(field, "table.colour");
    assert!(message.contains("unknown field `colour`"), "{message}");
}

#[test]
fn a_missing_field_is_named() {
    let bad = GOOD.replace("height_m = 0.7\n", "");
    let (_, field, message) = error_of(&bad);
    assert_eq!(field, "table");
    assert!(message.contains("missing field `height_m`"), "{message}");
}

#[test]
fn a_syntax_error_names_its_line() {
    let bad = GOOD.replace("seed = 3", "seed = = 3");
    let (line, _, _) = error_of(&bad);
    assert_eq!(line, 2);
}

#[test]
fn an_out_of_range_value_names_its_line_and_field() {
    let bad = GOOD.replace("focal_px = 900.0\nposition_m = [-0.1", "focal_px = -5.0\nposition_m = [-0.1");
    let (line, field, message) = error_of(&bad);
    assert_eq!((line, field.as_str()), (8, "cameras.left.focal_px"));
    assert!(message.contains("must be within") && message.contains("got -5"), "{message}");
    let bad = GOOD.to_string() + "[[bins]]\nname = \"a\"\ncentre_m = [0.3, 0.0]\nsize_m = [0.2, 0.0, 0.05]\n";
    let (line, field, _) = error_of(&bad);
    assert_eq!((line, field.as_str()), (21, "bins[0].size_m[1]"));
}

#[test]
fn an_unknown_model_names_its_line_and_field() {
    let bad = GOOD.replace("model = \"block\"", "model = \"teapot\"");
    let w = WorldFile::parse(&bad, "w.toml").unwrap();
    let lib = mesh::Library::load_default().unwrap();
    match w.check_models(&lib, &bad, "w.toml") {
        Err(WorldError::Invalid { line, field, message, .. }) => {
            assert_eq!((line, field.as_str()), (16, "objects[0].model"));
            assert!(message.contains("teapot") && message.contains("widget"), "{message}");
        }
        other => panic!("expected an error, got {other:?}"),
    }
}

#[test]
fn a_non_finite_number_anywhere_names_its_field() {
    for (from, to, field) in [
        ("position_m = [-0.1, -0.7, 0.6]", "position_m = [-0.1, nan, 0.6]", "cameras.left.position_m[1]"),
        ("albedo = 0.3", "albedo = inf", "table.albedo"),
        ("position_m = [0.0, 0.0, 0.015]", "position_m = [0.0, 0.0, -inf]", "objects[0].position_m[2]"),
    ] {
        let (line, f, message) = error_of(&GOOD.replace(from, to));
        assert_eq!(f, field, "{to}");
        assert!(message.contains("finite"), "{message}");
        assert_eq!(GOOD.replace(from, to).lines().nth(line - 1).map(|l| l.contains(to)), Some(true), "line {line}");
    }
}

#[test]
fn the_realism_preset_and_its_effects_are_read_and_bad_ones_named() {
    let w = WorldFile::parse(GOOD, "w.toml").unwrap();
    assert_eq!(w.realism, Preset::Realistic);
    assert!(w.effects().sensor && w.effects().arm_as_built);
    let ideal = GOOD.replace("seed = 3", "seed = 3\nrealism = \"ideal\"\n[effects]\nblur = true");
    let w = WorldFile::parse(&ideal, "w.toml").unwrap();
    assert!(w.effects().blur && !w.effects().sensor);
    let (line, field, message) = error_of(&GOOD.replace("seed = 3", "seed = 3\nrealism = \"photoreal\""));
    assert_eq!((line, field.as_str()), (3, "realism"));
    assert!(message.contains("unknown variant"), "{message}");
    let bad_lens = GOOD.replace(
        "focal_px = 900.0\nposition_m = [0.1",
        "focal_px = 900.0\nlens = { f_number = 0.1 }\nposition_m = [0.1",
    );
    let (line, field, message) = error_of(&bad_lens);
    assert_eq!((line, field.as_str()), (13, "cameras.right.lens.f_number"));
    assert!(message.contains("must be within"), "{message}");
}

#[test]
fn a_clutter_count_of_zero_is_refused() {
    let with_clutter = GOOD.to_string()
        + "[clutter]\nregion_m = { min = [-0.1, -0.1], max = [0.1, 0.1] }\nobjects = [{ model = \"block\", count = 0 }]\n";
    let (line, field, message) = error_of(&with_clutter);
    assert_eq!((line, field.as_str()), (20, "clutter.objects[0].count"));
    assert!(message.contains("got 0"), "{message}");
    assert!(WorldFile::parse(&with_clutter.replace("count = 0", "count = 2"), "w.toml").is_ok());
}

#[test]
fn incoherent_cameras_are_refused() {
    let same_place = GOOD.replace("position_m = [0.1, -0.7, 0.6]", "position_m = [-0.1, -0.7, 0.6]");
    let (_, field, message) = error_of(&same_place);
    assert_eq!(field, "cameras.right.position_m");
    assert!(message.contains("baseline"), "{message}");
    // Looking straight down with the default up (+z): no image 'up'.
    let straight_down = GOOD.replace(
        "position_m = [-0.1, -0.7, 0.6]\nlook_at_m = [0.0, 0.0, 0.0]",
        "position_m = [0.0, 0.0, 0.6]\nlook_at_m = [0.0, 0.0, 0.0]",
    );
    let (_, field, message) = error_of(&straight_down);
    assert_eq!(field, "cameras.left.up");
    assert!(message.contains("parallel"), "{message}");
    let off_image = GOOD.replace(
        "focal_px = 900.0\nposition_m = [0.1",
        "focal_px = 900.0\nprincipal_point = [600.0, 10.0]\nposition_m = [0.1",
    );
    assert_eq!(error_of(&off_image).1, "cameras.right.principal_point");
}

#[test]
fn values_out_of_their_range_are_refused_naming_them() {
    let cases = [
        (
            "seed = 3",
            "seed = 3\n[physics]\ntimestep_s = 0.5\nsettle_limit_s = 8.0\nfriction = 0.7",
            "physics.timestep_s",
        ),
        (
            "seed = 3",
            "seed = 3\n[physics]\ntimestep_s = 0.004\nsettle_limit_s = 8.0\nfriction = -1.0",
            "physics.friction",
        ),
        ("seed = 3", "seed = 3\n[light]\ndirection = [0.0, 0.0, 1.0]\ndiffuse = 3.0\nambient = 0.2", "light.diffuse"),
        ("seed = 3", "seed = 3\n[render]\nnoise_sigma = -2.0", "render.noise_sigma"),
    ];
    for (from, to, field) in cases {
        let (line, f, message) = error_of(&GOOD.replace(from, to));
        assert_eq!(f, field, "{to}: {message}");
        assert!(message.contains("must be within"), "{message}");
        let key = field.rsplit('.').next().unwrap();
        assert!(GOOD.replace(from, to).lines().nth(line - 1).unwrap().starts_with(key), "{field} at line {line}");
    }
    let off_table = GOOD.to_string() + "[[bins]]\nname = \"a\"\ncentre_m = [0.45, 0.0]\nsize_m = [0.2, 0.2, 0.05]\n";
    let (_, field, message) = error_of(&off_table);
    assert_eq!(field, "bins[0].centre_m[0]");
    assert!(message.contains("edge"), "{message}");
}
