//! Hyperelastic material entries of a body's `constraints`
//! (`kind = "neo-hookean" | "stvk" | "corotated"`, `young` in Pa, `poisson`
//! in `[0, 0.5)`; docs/design/materials.md), and the rule that they need an
//! objective-judging method (`solver.method = "lbfgs"` or `"newton"`).

use pd_constraints::MaterialKind;
use pd_solver::SolverSpec;

use super::raw;
use super::spec::{BodySpec, ConstraintSpec};
use super::validate::Validator;
use crate::Result;

impl Validator<'_> {
    /// The material entry `field` (`body[0].constraints[1]`) of law `kind`.
    pub(super) fn material(
        &self,
        field: &str,
        kind: MaterialKind,
        raw: &raw::Constraint,
    ) -> Result<ConstraintSpec> {
        let sub = |name: &str| format!("{field}.{name}");
        let foreign = [
            ("stiffness", raw.stiffness.is_some()),
            ("limits", raw.limits.is_some()),
            ("vertices", raw.vertices.is_some()),
            ("box", raw.bounds.is_some()),
        ];
        if let Some((name, _)) = foreign.iter().find(|(_, given)| *given) {
            return Err(self.field(
                sub(name),
                format!(
                    "is not a parameter of {}; a material takes young (Pa) and poisson",
                    kind.name()
                ),
            ));
        }
        let young = raw
            .young
            .ok_or_else(|| self.field(sub("young"), "missing"))?;
        let poisson = raw
            .poisson
            .ok_or_else(|| self.field(sub("poisson"), "missing"))?;
        if !(young > 0.0 && young.is_finite()) {
            return Err(self.field(
                sub("young"),
                format!("must be finite and > 0 Pa, got {young}"),
            ));
        }
        if !(0.0..0.5).contains(&poisson) {
            return Err(self.field(
                sub("poisson"),
                format!("must be in [0, 0.5), got {poisson}"),
            ));
        }
        Ok(ConstraintSpec::Material {
            kind,
            young,
            poisson,
        })
    }

    /// `young` and `poisson` given to a kind that is not a material.
    pub(super) fn no_material_keys(&self, field: &str, raw: &raw::Constraint) -> Result<()> {
        for (name, given) in [
            ("young", raw.young.is_some()),
            ("poisson", raw.poisson.is_some()),
        ] {
            if given {
                return Err(self.field(
                    format!("{field}.{name}"),
                    format!("is not a parameter of {}", raw.kind),
                ));
            }
        }
        Ok(())
    }

    /// A material with a method that only minimises PD's quadratic energies
    /// is an error at `solver.method`, naming the material's entry.
    pub(super) fn check_material_method(
        &self,
        bodies: &[BodySpec],
        solver: &SolverSpec,
    ) -> Result<()> {
        if !solver.method.pd_only() {
            return Ok(());
        }
        for (b, body) in bodies.iter().enumerate() {
            for (c, constraint) in body.constraints.iter().enumerate() {
                if let ConstraintSpec::Material { kind, .. } = constraint {
                    return Err(self.field(
                        "solver.method",
                        format!(
                            "method \"{}\" cannot run the non-quadratic material \"{}\" of \
                             body[{b}].constraints[{c}]: it only minimises Projective Dynamics' \
                             quadratic energies; use \"lbfgs\" or \"newton\"",
                            solver.method.name(),
                            kind.name()
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}
