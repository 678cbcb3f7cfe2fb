//! Scene loader, parse and validation (the same entry as `Scene::load`
//! after the file is read): an even first byte reads the rest as TOML, an
//! odd one as JSON. Any text gives a scene or an error value (no panic, no
//! abort, no hang); a parse error names a line of the text. Building the
//! scene is not fuzzed: it reads the mesh files the scene names and
//! factorises the system, too slow per input.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use pd_fuzz::{check_error, line_count};
use pd_io::scene::{Scene, Syntax};

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(rest) else {
        return;
    };
    let (syntax, source) = if mode % 2 == 0 {
        (Syntax::Toml, Path::new("fuzz/scene.toml"))
    } else {
        (Syntax::Json, Path::new("fuzz/scene.json"))
    };
    if let Err(error) = Scene::parse(text, syntax, source) {
        check_error(&error, &[(source, line_count(rest))]);
    }
});
