//! `[solver] predictor_order` and `predictor_window`, the fitted
//! predictor's `k` and `m` (`pd_solver::Predictor::Fitted`,
//! docs/reference/scene-format.md).

use pd_solver::Predictor;

use super::solver::Solver;
use super::validate::Validator;
use crate::Result;

/// `predictor` with the raw table's `predictor_order` and
/// `predictor_window` applied: only with `predictor = "fitted"`, `1 <= k
/// <= 12`, `k <= m <= 24` (`m` defaults to `2 k`).
pub(super) fn fitted_keys(
    validator: &Validator<'_>,
    raw: Option<&Solver>,
    predictor: Predictor,
) -> Result<Predictor> {
    let order = raw.and_then(|r| r.predictor_order);
    let window = raw.and_then(|r| r.predictor_window);
    let Predictor::Fitted {
        order: default_order,
        equations: default_window,
    } = predictor
    else {
        for (key, value) in [("predictor_order", order), ("predictor_window", window)] {
            if value.is_some() {
                return Err(validator.field(
                    format!("solver.{key}"),
                    "applies only with predictor = \"fitted\"".to_string(),
                ));
            }
        }
        return Ok(predictor);
    };
    let order = order.unwrap_or(default_order);
    if !(1..=Predictor::MAX_ORDER).contains(&order) {
        return Err(validator.field(
            "solver.predictor_order",
            format!(
                "must be between 1 and {}, got {order}",
                Predictor::MAX_ORDER
            ),
        ));
    }
    let fallback = if order == default_order {
        default_window
    } else {
        order.saturating_mul(2).min(Predictor::MAX_EQUATIONS)
    };
    let equations = window.unwrap_or(fallback);
    if equations < order || equations > Predictor::MAX_EQUATIONS {
        return Err(validator.field(
            "solver.predictor_window",
            format!(
                "must be between predictor_order ({order}) and {}, got {equations}",
                Predictor::MAX_EQUATIONS
            ),
        ));
    }
    Ok(Predictor::Fitted { order, equations })
}
