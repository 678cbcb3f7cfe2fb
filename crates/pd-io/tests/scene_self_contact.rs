//! `[contact] self = true` (docs/reference/scene-format.md, "Self-contact"): read,
//! combined independently with `bodies`, and built into a simulation.

use std::path::Path;

use pd_io::scene::{Scene, Syntax};
use pd_solver::contact::SurfacePairs;

const SHEET: &str = r#"[simulation]
dt = 0.01
steps = 10

[[body]]
mesh = { generator = "cloth", size = [0.2, 0.2], cells = [4, 4] }
density = 0.2
constraints = [ { kind = "triangle-strain", stiffness = 5.0e3 } ]
"#;

fn parse(contact: &str) -> pd_io::Result<Scene> {
    let text = format!("{SHEET}\n[contact]\n{contact}");
    Scene::parse(&text, Syntax::Toml, Path::new("scenes/self.toml"))
}

#[test]
fn self_and_bodies_are_read_independently() {
    let cases = [
        ("self = true\n", true, false),
        ("bodies = true\n", false, true),
        ("self = true\nbodies = true\n", true, true),
        ("self = false\nbodies = false\n", false, false),
    ];
    for (keys, self_contact, between_bodies) in cases {
        let scene = parse(keys).unwrap();
        assert_eq!(
            scene.surface_pairs,
            SurfacePairs {
                between_bodies,
                self_contact,
            },
            "{keys}"
        );
        assert_eq!(
            scene.body_contact.is_some(),
            self_contact || between_bodies,
            "{keys}"
        );
        assert_eq!(
            scene.build().unwrap().contact().is_some(),
            scene.body_contact.is_some()
        );
    }
}

#[test]
fn self_contact_takes_the_contact_friction_and_thickness() {
    let scene = parse("self = true\nfriction = 0.4\nthickness = 0.002\n").unwrap();
    assert_eq!(scene.body_contact.as_ref().unwrap().friction, 0.4);
    assert_eq!(scene.contact.as_ref().unwrap().thickness, 0.002);
    let mut simulation = scene.build().unwrap();
    simulation.run(3).unwrap();
    // A negative friction is refused with its field, as with `bodies`.
    let message = parse("self = true\nfriction = -1.0\n")
        .unwrap_err()
        .to_string();
    assert!(message.contains("contact.friction"), "{message}");
}
