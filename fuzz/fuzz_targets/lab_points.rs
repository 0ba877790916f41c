//! The lab's `visibility --points` CSV: a typed error naming the line, or finite points.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data)
        && let Ok(points) = shadow_fins_lab::points::parse_points(text)
    {
        assert!(points.iter().all(|(p, n)| p.is_finite() && n.is_finite()));
    }
});
