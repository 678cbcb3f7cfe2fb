//! TetGen reader: the input is a mode byte, the `.node` file, a NUL byte and
//! the element file. An even mode byte reads a tetrahedral mesh
//! (`.node` + `.ele`), an odd one a surface (`.node` + `.face`). Any bytes
//! give a mesh or an error value; a parse error names a line of the file it
//! is in.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pd_fuzz::{check_error, line_count, scratch_file, split_nul};

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let (node_bytes, element_bytes) = split_nul(rest);
    let node = scratch_file("input.1.node", node_bytes);
    let result = if mode % 2 == 0 {
        let ele = scratch_file("input.1.ele", element_bytes);
        pd_io::tetgen::read_tetgen(&node, &ele)
            .map(|_| ())
            .map_err(|e| (e, ele))
    } else {
        let face = scratch_file("input.1.face", element_bytes);
        pd_io::tetgen::read_tetgen_surface(&node, &face)
            .map(|_| ())
            .map_err(|e| (e, face))
    };
    if let Err((error, elements)) = result {
        check_error(
            &error,
            &[
                (&node, line_count(node_bytes)),
                (&elements, line_count(element_bytes)),
            ],
        );
    }
});
