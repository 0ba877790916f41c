//! The lab's command line: real runs of the binary, good and bad input.

use std::process::Command;

fn lab(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_shadow-fins-lab")).args(args).output().expect("run shadow-fins-lab")
}

fn temp(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("shadow-fins-lab-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn visibility_writes_one_row_per_point_and_methods_agree_where_they_must() {
    let points = temp("points.csv");
    // Under the box's shadow centre (umbra), and far away (lit).
    std::fs::write(&points, "x,y,z,nx,ny,nz\n-0.24,0,-0.16,0,1,0\n4,0,4,0,1,0\n").unwrap();
    for method in [
        "ground-truth",
        "fins",
        "hard",
        "outer-fins",
        "single-layer",
        "coverage",
        "single-sample",
        "plateaus",
        "penumbra-wedges",
        "wedge-blending",
    ] {
        let out =
            lab(&["visibility", "--scene", "box-over-plane", "--points", points.to_str().unwrap(), "--method", method]);
        assert!(out.status.success(), "{method}: {}", String::from_utf8_lossy(&out.stderr));
        let text = String::from_utf8(out.stdout).unwrap();
        let values: Vec<f32> = text.lines().skip(1).map(|l| l.rsplit(',').next().unwrap().parse().unwrap()).collect();
        assert_eq!(values.len(), 2, "{method}");
        assert!(values[0] < 0.01 && values[1] > 0.999, "{method}: {values:?}");
    }
}

#[test]
fn the_raster_oracle_and_settings_flags_are_accepted() {
    let points = temp("points2.csv");
    std::fs::write(&points, "0.9,0,0.7\n").unwrap();
    let out = lab(&[
        "visibility",
        "--scene",
        "box-over-plane",
        "--points",
        points.to_str().unwrap(),
        "--method",
        "fins",
        "--map-resolution",
        "256",
        "--layers",
        "4",
        "--sub-layers",
        "64",
        "--no-refinement",
        "--falloff",
        "bernstein",
        "--overlap",
        "min-max",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: f32 =
        String::from_utf8(out.stdout).unwrap().lines().nth(1).unwrap().rsplit(',').next().unwrap().parse().unwrap();
    assert!((0.0..=1.0).contains(&v));
}

#[test]
fn bad_input_gets_a_clear_error_and_a_non_zero_exit() {
    let points = temp("points3.csv");
    std::fs::write(&points, "0,0,0\n").unwrap();
    let p = points.to_str().unwrap();
    let cases: [(&[&str], &str); 6] = [
        (&["visibility", "--points", p, "--radius", "-1"], "radius -1"),
        (&["visibility", "--points", p, "--layers", "0"], "layer count 0"),
        (&["visibility", "--points", p, "--method", "magic"], "unknown method"),
        (&["visibility", "--points", p, "--method", "coverage", "--coverage-samples", "0"], "--coverage-samples 0"),
        (&["visibility", "--points", p, "--scene", "nowhere"], "unknown scene"),
        (&["visibility", "--points", "/nonexistent.csv"], "/nonexistent.csv"),
    ];
    for (args, expected) in cases {
        let out = lab(args);
        assert!(!out.status.success(), "{args:?} should fail");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(expected), "{args:?}: stderr was {err}");
    }
    let broken = temp("broken.gltf");
    std::fs::write(&broken, "{ this is not json").unwrap();
    let out = lab(&["visibility", "--points", p, "--gltf", broken.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a valid glTF"));
    std::fs::write(&points, "0,nan,0\n").unwrap();
    let out = lab(&["visibility", "--points", p]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("line 1"));
}

#[test]
fn image_writes_a_png_strip_that_is_not_blank() {
    let png = temp("strip.png");
    let out = lab(&[
        "image",
        "--scene",
        "box-over-plane",
        "--width",
        "48",
        "--height",
        "36",
        "--samples",
        "64",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(
        table.contains("| hard |")
            && table.contains("| fins 16L |")
            && table.contains("| fins 16L paper |")
            && table.contains("| single-sample |")
            && table.contains("| plateaus |")
            && table.contains("| penumbra-wedges |")
            && table.contains("| wedge-blending |")
            && table.contains("| convolution |"),
        "{table}"
    );
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    // Decode and check the picture has both dark and bright pixels (not a black image).
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let data = &buf[..info.buffer_size()];
    let (dark, bright) = (data.iter().filter(|&&b| b < 20).count(), data.iter().filter(|&&b| b > 235).count());
    assert!(dark > 100 && bright > 100, "dark {dark}, bright {bright}");
}

#[test]
fn exported_gltf_round_trips_through_the_cli() {
    let gltf = temp("scene.gltf");
    let out = lab(&["export-gltf", "--scene", "star-prism", "--out", gltf.to_str().unwrap()]);
    assert!(out.status.success());
    let points = temp("points4.csv");
    std::fs::write(&points, "0,0,0,0,1,0\n").unwrap();
    let out = lab(&[
        "visibility",
        "--gltf",
        gltf.to_str().unwrap(),
        "--light-center",
        "0,4,0",
        "--radius",
        "0.5",
        "--points",
        points.to_str().unwrap(),
        "--method",
        "fins",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // The star's centre is right above the origin: full umbra there.
    let v: f32 =
        String::from_utf8(out.stdout).unwrap().lines().nth(1).unwrap().rsplit(',').next().unwrap().parse().unwrap();
    assert!(v < 0.01, "{v}");
}
