//! No input makes a mesh reader panic: arbitrary bytes, and valid fixtures
//! with random edits (a byte replaced, a line dropped or duplicated, the
//! file cut short). Each reader either returns a mesh or an error; a parse
//! error must point at a line of the file. Case counts are bounded so the
//! whole file runs in a few seconds.

mod common;

use std::path::Path;

use pd_io::Error;
use pd_io::gmsh::read_gmsh;
use pd_io::medit::read_medit;
use pd_io::obj::read_obj;
use pd_io::tetgen::read_tetgen_surface;
use pd_mesh::Mesh;
use proptest::prelude::*;

type Reader = fn(&Path) -> Result<Mesh, Error>;

fn read_face(path: &Path) -> Result<Mesh, Error> {
    let node = common::data_dir().join("formats").join("two_tets.1.node");
    read_tetgen_surface(&node, path)
}

const READERS: [(&str, &str, Reader); 4] = [
    ("two_tets.msh", "msh", read_gmsh),
    ("two_tets.mesh", "mesh", read_medit),
    ("quad_cloth.obj", "obj", read_obj),
    ("two_tets.1.face", "face", read_face),
];

/// Writes `bytes` to a scratch file and reads it with every reader; checks
/// that a parse error names a line that exists.
fn read_with_all(dir: &Path, bytes: &[u8]) {
    let lines = bytes.iter().filter(|&&b| b == b'\n').count() + 1;
    for (_, extension, read) in READERS {
        let path = dir.join(format!("input.{extension}"));
        std::fs::write(&path, bytes).unwrap();
        if let Err(Error::Parse { line, .. }) = read(&path) {
            assert!(
                (1..=lines).contains(&line),
                "line {line} of a {lines}-line file"
            );
        }
    }
}

/// A random edit of a valid fixture.
#[derive(Debug, Clone)]
enum Edit {
    Byte { at: usize, value: u8 },
    DropLine(usize),
    DuplicateLine(usize),
    Truncate(usize),
    ReplaceToken { at: usize, token: &'static str },
}

fn apply(text: &str, edit: &Edit) -> Vec<u8> {
    let mut lines: Vec<&str> = text.lines().collect();
    match *edit {
        Edit::Byte { at, value } => {
            let mut bytes = text.as_bytes().to_vec();
            let at = at % bytes.len();
            bytes[at] = value;
            bytes
        }
        Edit::DropLine(at) => {
            lines.remove(at % lines.len());
            lines.join("\n").into_bytes()
        }
        Edit::DuplicateLine(at) => {
            let at = at % lines.len();
            lines.insert(at, lines[at]);
            lines.join("\n").into_bytes()
        }
        Edit::Truncate(at) => text.as_bytes()[..at % text.len()].to_vec(),
        Edit::ReplaceToken { at, token } => {
            let mut tokens: Vec<&str> = text.split(' ').collect();
            let at = at % tokens.len();
            tokens[at] = token;
            tokens.join(" ").into_bytes()
        }
    }
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(at, value)| Edit::Byte { at, value }),
        any::<usize>().prop_map(Edit::DropLine),
        any::<usize>().prop_map(Edit::DuplicateLine),
        any::<usize>().prop_map(Edit::Truncate),
        (
            any::<usize>(),
            prop::sample::select(vec![
                "-1",
                "0",
                "99999999999999999999",
                "1e308",
                "nan",
                "inf",
                "-0",
                "1.5",
                "",
                "$EndNodes",
                "End",
                "f",
                "\n",
            ])
        )
            .prop_map(|(at, token)| Edit::ReplaceToken { at, token }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
        let dir = common::scratch_dir("fuzz_bytes");
        read_with_all(&dir, &bytes);
    }

    #[test]
    fn edited_fixtures_never_panic(edits in prop::collection::vec(edit(), 1..4), which in 0usize..4) {
        let dir = common::scratch_dir("fuzz_edits");
        let text = std::fs::read_to_string(common::data_dir().join("formats").join(READERS[which].0)).unwrap();
        let mut bytes = text.into_bytes();
        for e in &edits {
            let current = String::from_utf8_lossy(&bytes).into_owned();
            if current.is_empty() {
                break;
            }
            bytes = apply(&current, e);
        }
        read_with_all(&dir, &bytes);
    }
}

#[test]
fn every_fixture_reads_unedited() {
    // The edits above start from inputs that are valid.
    for (name, _, read) in READERS {
        read(&common::data_dir().join("formats").join(name)).unwrap();
    }
}
