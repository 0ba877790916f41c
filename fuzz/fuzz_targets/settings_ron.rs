//! The editor's settings RON: a typed error, or settings that apply clamped
//! (finite light, settings in their documented ranges).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        shadow_fins_editor::check_settings_text(text);
    }
});
