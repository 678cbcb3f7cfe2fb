//! `[solver] predictor` (and the fitted predictor's `predictor_order` and
//! `predictor_window`): read as written, reported at their field path, and
//! carried through a checkpoint file so that a resumed run continues bit
//! for bit.

use std::path::Path;

use pd_io::checkpoint::{CheckpointFile, SceneText, read_checkpoint, write_checkpoint};
use pd_io::scene::{Scene, Syntax};
use pd_solver::Predictor;

fn scene(solver: &str) -> String {
    format!(
        "[simulation]\ndt = 0.01\nsteps = 1\n\n{solver}\n\n[[body]]\n\
         mesh = {{ generator = \"chain\", points = 4, length = 1.0 }}\nvertex_mass = 0.1\n\
         constraints = [{{ kind = \"spring\", stiffness = 50.0 }}]\nfixed = {{ vertices = [0] }}\n"
    )
}

fn parse(solver: &str) -> pd_io::Result<Scene> {
    Scene::parse(&scene(solver), Syntax::Toml, Path::new("s.toml"))
}

#[test]
fn the_predictor_is_read_as_written() {
    let s = parse("").unwrap();
    assert_eq!(s.predictor, Predictor::Inertial);
    assert_eq!(s.build().unwrap().predictor(), Predictor::Inertial);
    for predictor in Predictor::ALL {
        let table = format!(
            "[solver]\nmethod = \"anderson\"\npredictor = \"{}\"",
            predictor.name()
        );
        let s = parse(&table).unwrap();
        assert_eq!(s.predictor, predictor);
        assert_eq!(s.build().unwrap().predictor(), predictor);
    }
}

#[test]
fn an_unknown_predictor_names_the_field() {
    let error = parse("[solver]\npredictor = \"quadratic\"")
        .unwrap_err()
        .to_string();
    assert_eq!(
        error,
        "s.toml: solver.predictor: unknown predictor \"quadratic\"; expected one of: \
         inertial, extrapolated, linear, fitted"
    );
}

#[test]
fn order_and_window_are_read_as_written() {
    let fitted = |extra: &str| {
        parse(&format!("[solver]\npredictor = \"fitted\"\n{extra}"))
            .unwrap()
            .predictor
    };
    assert_eq!(fitted(""), Predictor::FITTED);
    let at = |order, equations| Predictor::Fitted { order, equations };
    assert_eq!(fitted("predictor_order = 3"), at(3, 6));
    assert_eq!(fitted("predictor_order = 12"), at(12, 24));
    assert_eq!(
        fitted("predictor_order = 3\npredictor_window = 3"),
        at(3, 3)
    );
    assert_eq!(fitted("predictor_window = 20"), at(4, 20));
    let s = parse("[solver]\npredictor = \"fitted\"\npredictor_order = 5").unwrap();
    assert_eq!(s.build().unwrap().predictor(), at(5, 10));
}

#[test]
fn bad_keys_name_their_field() {
    for (extra, field) in [
        (
            "predictor = \"fitted\"\npredictor_order = 0",
            "solver.predictor_order",
        ),
        (
            "predictor = \"fitted\"\npredictor_order = 13",
            "solver.predictor_order",
        ),
        (
            "predictor = \"fitted\"\npredictor_order = 4\npredictor_window = 3",
            "solver.predictor_window",
        ),
        (
            "predictor = \"fitted\"\npredictor_window = 25",
            "solver.predictor_window",
        ),
        (
            "predictor = \"linear\"\npredictor_order = 4",
            "solver.predictor_order",
        ),
        ("predictor_window = 4", "solver.predictor_window"),
    ] {
        let error = parse(&format!("[solver]\n{extra}"))
            .unwrap_err()
            .to_string();
        assert!(
            error.starts_with(&format!("s.toml: {field}: ")),
            "{extra}: {error}"
        );
    }
}

/// Saves `a`'s checkpoint through a checkpoint file and checks that a
/// simulation restored from the file continues as `a` for 3 steps, bit for
/// bit; `tag` names the temporary directory.
fn resumes_through_a_file(table: &str, mut a: pd_solver::Simulation, tag: &str) {
    let saved = a.checkpoint();
    let dir = std::env::temp_dir().join(format!("pd-io-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("checkpoint.json");
    let file = CheckpointFile {
        scene: SceneText {
            source: "s.toml".into(),
            syntax: Syntax::Toml,
            text: scene(table),
        },
        steps_requested: 9,
        threads: 1,
        checkpoint_every: 3,
        checkpoint: saved,
        method: None,
    };
    write_checkpoint(&path, &file).unwrap();
    let back = read_checkpoint(&path).unwrap();
    assert_eq!(back, file);
    a.run(3).unwrap();
    let mut b = parse(table).unwrap().build().unwrap();
    b.restore(&back.checkpoint).unwrap();
    b.run(3).unwrap();
    let bits = |s: &pd_solver::State| -> Vec<u64> {
        s.positions
            .iter()
            .chain(&s.velocities)
            .flat_map(|p| p.iter().map(|x| x.to_bits()))
            .collect()
    };
    assert_eq!(bits(a.state()), bits(b.state()));
    std::fs::remove_dir_all(&dir).ok();
}

/// The predictor's corrections go through the checkpoint file with every
/// bit: a simulation restored from the file continues as the saved one.
#[test]
fn a_checkpoint_file_keeps_the_corrections() {
    let table = "[solver]\nmethod = \"anderson\"\npredictor = \"linear\"";
    let mut a = parse(table).unwrap().build().unwrap();
    a.run(3).unwrap();
    let saved = a.checkpoint();
    assert_eq!(saved.predictor.correction.len(), 4);
    assert_eq!(saved.predictor.previous.len(), 4);
    resumes_through_a_file(table, a, "predictor");
}

/// The fitted predictor's older corrections go through the checkpoint file
/// with every bit: a simulation restored from the file continues as the
/// saved one.
#[test]
fn a_checkpoint_file_keeps_the_history() {
    let table = "[solver]\nmethod = \"anderson\"\npredictor = \"fitted\"\n\
                 predictor_order = 2\npredictor_window = 2";
    let mut a = parse(table).unwrap().build().unwrap();
    a.run(6).unwrap();
    assert_eq!(a.checkpoint().predictor.history.len(), 2);
    resumes_through_a_file(table, a, "fitted");
}
