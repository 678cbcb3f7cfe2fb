//! Checkpoint reader (`read_checkpoint`): any bytes give a checkpoint or an
//! error value (no panic, no abort, no hang); a parse error names a line of
//! the file.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pd_fuzz::{check_error, line_count, scratch_file};

fuzz_target!(|data: &[u8]| {
    let path = scratch_file("input.checkpoint.json", data);
    if let Err(error) = pd_io::checkpoint::read_checkpoint(&path) {
        check_error(&error, &[(&path, line_count(data))]);
    }
});
