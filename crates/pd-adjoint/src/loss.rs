//! Losses on a trajectory: the built-in probe loss and the [`Loss`] trait
//! for a user's own.

use pd_mesh::Point;

/// A loss on the positions of a run: a sum of terms, one per step
/// `1..=steps` (the state after each step; the initial state carries no
/// term).
pub trait Loss {
    /// The term of step `step` (1-based) at the positions `x` (one point per
    /// vertex, m).
    fn value(&self, step: usize, x: &[Point]) -> f64;
    /// The gradient of that term with respect to `x` (one point per vertex),
    /// written into `out` (zeroed by the caller).
    fn gradient(&self, step: usize, x: &[Point], out: &mut [Point]);
    /// The number of steps the loss is defined for, if it is fixed: a run
    /// of any other length is refused. `None` (the default): any.
    fn steps(&self) -> Option<usize> {
        None
    }
    /// Checks the loss against a model of `vertices` vertices (e.g. that
    /// its vertex indices exist), naming what is wrong.
    ///
    /// # Errors
    /// The reason, when the loss cannot be evaluated on such a model.
    fn check(&self, vertices: usize) -> Result<(), String> {
        let _ = vertices;
        Ok(())
    }
}

/// The built-in loss: the mean over steps and probe vertices of the squared
/// distance from each probe vertex to its target, in m^2,
///
/// `L = 1/(S P) sum_{s=1..S} sum_p |x_s[vertices[p]] - targets[s-1][p]|^2`.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeLoss {
    /// The probe vertices (model numbering).
    pub vertices: Vec<usize>,
    /// The targets, `[step 1..=steps][probe]`, in m.
    pub targets: Vec<Vec<Point>>,
}

impl ProbeLoss {
    /// `1/(S P)`: the weight of each squared distance.
    fn weight(&self) -> f64 {
        1.0 / (self.targets.len() * self.vertices.len()) as f64
    }
}

impl Loss for ProbeLoss {
    fn value(&self, step: usize, x: &[Point]) -> f64 {
        let Some(targets) = step.checked_sub(1).and_then(|s| self.targets.get(s)) else {
            return 0.0;
        };
        let sum: f64 = self
            .vertices
            .iter()
            .zip(targets)
            .map(|(&v, t)| (x[v] - t).norm_squared())
            .sum();
        sum * self.weight()
    }

    fn gradient(&self, step: usize, x: &[Point], out: &mut [Point]) {
        let Some(targets) = step.checked_sub(1).and_then(|s| self.targets.get(s)) else {
            return;
        };
        let weight = 2.0 * self.weight();
        for (&v, t) in self.vertices.iter().zip(targets) {
            out[v] += (x[v] - t) * weight;
        }
    }

    fn steps(&self) -> Option<usize> {
        Some(self.targets.len())
    }

    fn check(&self, vertices: usize) -> Result<(), String> {
        if self.vertices.is_empty() {
            return Err("the probe loss has no probe vertex".into());
        }
        if let Some(v) = self.vertices.iter().find(|&&v| v >= vertices) {
            return Err(format!(
                "probe vertex {v} is out of range: the model has {vertices} vertices"
            ));
        }
        for (s, targets) in self.targets.iter().enumerate() {
            if targets.len() != self.vertices.len() {
                return Err(format!(
                    "step {} has {} targets for {} probe vertices",
                    s + 1,
                    targets.len(),
                    self.vertices.len()
                ));
            }
            if let Some(p) = targets
                .iter()
                .position(|t| !t.iter().all(|c| c.is_finite()))
            {
                return Err(format!(
                    "the target of probe {p} at step {} is not finite",
                    s + 1
                ));
            }
        }
        Ok(())
    }
}
