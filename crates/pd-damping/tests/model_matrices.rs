//! Each model's name and the implicit matrix and flags it hands the solver.

use pd_damping::{
    Damping, DampingMatrix, EtherDrag, LaplacianDamping, NoDamping, PbdDamping, RayleighLagged,
};

#[test]
fn names_are_as_scenes_spell_them() {
    assert_eq!(EtherDrag::factor(0.1).unwrap().name(), "ether-drag");
    assert_eq!(EtherDrag::rate(0.1).unwrap().name(), "ether-drag");
    assert_eq!(EtherDrag::implicit(0.1).unwrap().name(), "ether-drag");
    assert_eq!(PbdDamping::new(0.1).unwrap().name(), "pbd");
    assert_eq!(
        LaplacianDamping::new(0.1, 0.0, false).unwrap().name(),
        "laplacian"
    );
    assert_eq!(
        RayleighLagged::new(0.1, 0.0).unwrap().name(),
        "rayleigh-lagged"
    );
}

#[test]
fn laplacian_is_constant_and_reports_rotation_preservation() {
    for preserve_rotation in [false, true] {
        let damping = LaplacianDamping::new(0.02, 0.3, preserve_rotation).unwrap();
        let matrix = damping.implicit_matrix();
        assert_eq!(
            matrix,
            DampingMatrix {
                mass: 0.3,
                damping_laplacian: 0.02,
                lagged_stiffness: 0.0,
                ..DampingMatrix::default()
            }
        );
        assert!(!matrix.is_lagged());
        assert_eq!(damping.preserves_rotation(), preserve_rotation);
        assert!(!damping.has_explicit_force());
    }
}

#[test]
fn rayleigh_lagged_is_lagged() {
    let matrix = RayleighLagged::new(0.02, 0.3).unwrap().implicit_matrix();
    assert_eq!(
        matrix,
        DampingMatrix {
            mass: 0.3,
            damping_laplacian: 0.0,
            lagged_stiffness: 0.02,
            ..DampingMatrix::default()
        }
    );
    assert!(matrix.is_lagged());
}

#[test]
fn only_laplacian_can_preserve_rotation() {
    let models: [Box<dyn Damping>; 4] = [
        Box::new(NoDamping),
        Box::new(EtherDrag::implicit(1.0).unwrap()),
        Box::new(PbdDamping::new(0.5).unwrap()),
        Box::new(RayleighLagged::new(1.0, 1.0).unwrap()),
    ];
    for model in &models {
        assert!(!model.preserves_rotation(), "{}", model.name());
        assert!(!model.has_explicit_force(), "{}", model.name());
    }
    assert!(PbdDamping::new(0.5).unwrap().implicit_matrix().is_zero());
}
