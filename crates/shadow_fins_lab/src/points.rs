//! The `visibility` command's points file: CSV lines `x,y,z` or
//! `x,y,z,nx,ny,nz` (world units; a normal of zero means "unknown"), blank lines
//! and `#` comments skipped, an optional header line first.
//!
//! Hostile input (fuzzed: `fuzz/fuzz_targets/lab_points.rs`, and the corpus test
//! below in the suite) is a typed [`LabError::Points`] naming the line, never a
//! panic; memory grows with the file's own size only.

use shadow_fins::glam::Vec3;

use crate::LabError;

/// A point and its normal (zero when the line gave none).
pub type Point = (Vec3, Vec3);

/// Parses a points file's text.
pub fn parse_points(text: &str) -> Result<Vec<Point>, LabError> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let nums: Result<Vec<f32>, _> = line.split(',').map(|f| f.trim().parse::<f32>()).collect();
        let nums = match nums {
            Ok(n) => n,
            Err(_) if i == 0 => continue, // header
            Err(_) => {
                return Err(LabError::Points { line: i + 1, reason: format!("'{}' is not numbers", shorten(line)) });
            }
        };
        if !(nums.len() == 3 || nums.len() == 6) || nums.iter().any(|v| !v.is_finite()) {
            return Err(LabError::Points {
                line: i + 1,
                reason: "need 3 or 6 finite numbers: x,y,z[,nx,ny,nz]".into(),
            });
        }
        let n = if nums.len() == 6 { Vec3::new(nums[3], nums[4], nums[5]) } else { Vec3::ZERO };
        out.push((Vec3::new(nums[0], nums[1], nums[2]), n));
    }
    Ok(out)
}

/// A line cut to at most 60 characters for an error message.
fn shorten(line: &str) -> String {
    match line.char_indices().nth(60) {
        Some((at, _)) => format!("{}…", &line[..at]),
        None => line.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn points_with_and_without_normals_a_header_and_comments() {
        let text = "x,y,z,nx,ny,nz\n# a comment\n1,2,3\n\n-1.5, 0 ,2e3, 0,1,0\n";
        let p = parse_points(text).unwrap();
        assert_eq!(p, vec![(Vec3::new(1.0, 2.0, 3.0), Vec3::ZERO), (Vec3::new(-1.5, 0.0, 2000.0), Vec3::Y)]);
    }

    #[test]
    fn bad_lines_are_typed_errors_that_name_the_line() {
        for (text, line) in [("1,2,3\nfoo\n", 2), ("1,2\n", 1), ("1,2,3\n1,NaN,3", 2), ("0,0,inf", 1), ("1,2,3,4", 1)] {
            match parse_points(text) {
                Err(LabError::Points { line: l, .. }) => assert_eq!(l, line, "{text:?}"),
                other => panic!("{text:?}: {other:?}"),
            }
        }
        // A huge line is reported, shortened.
        let long = format!("1,2,{}", "9".repeat(10_000)) + "x";
        let e = parse_points(&format!("0,0,0\n{long}")).unwrap_err().to_string();
        assert!(e.len() < 200, "{e}");
    }

    /// The fuzz target's seeds and every file it kept, run on the stable toolchain.
    #[test]
    fn the_fuzz_corpus_parses_without_panic_and_in_bounded_time() {
        let dir =
            std::path::Path::new(&std::env::var("CARGO_MANIFEST_DIR").unwrap()).join("../../fuzz/corpus/lab_points");
        let mut files = 0;
        for entry in std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
            let bytes = std::fs::read(entry.unwrap().path()).unwrap();
            let start = std::time::Instant::now();
            check_points(&bytes);
            assert!(start.elapsed().as_secs_f32() < 2.0, "slow input");
            files += 1;
        }
        assert!(files >= 5, "the seed corpus is committed ({files} files)");
    }

    /// What the fuzz target asserts of any input: no panic, and what parses is finite.
    pub(crate) fn check_points(bytes: &[u8]) {
        if let Ok(text) = std::str::from_utf8(bytes)
            && let Ok(points) = parse_points(text)
        {
            assert!(points.iter().all(|(p, n)| p.is_finite() && n.is_finite()));
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]
        #[test]
        fn generated_points_files_never_panic(lines in proptest::collection::vec("[-0-9eE.,# naif\\t]{0,40}", 0..20)) {
            check_points(lines.join("\n").as_bytes());
        }

        #[test]
        fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
            check_points(&bytes);
        }
    }
}
