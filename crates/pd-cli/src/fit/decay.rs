//! A decay description as `pd fit`'s target (Xu and Barbic's
//! artist-friendly input for example-based damping): the fraction of its
//! amplitude a probe loses per cycle, instead of a recording.
//!
//! ```toml
//! [decay]
//! probe = 2               # index into the scene's output.probes (default 0)
//! lost_per_cycle = 0.3    # fraction of the amplitude lost per cycle, in (0, 1)
//! direction = [0, 0, 1]   # optional: the motion measured (default: the
//!                         # coordinate axis along which the probe moves most)
//! ```
//!
//! The simulated decay is measured on the probe's position along
//! `direction`: its extrema (each refined by the parabola through
//! the three samples around it), the half-cycle swings `|e_{k+1} - e_k|`
//! (which do not depend on where the motion settles), and the mean decay
//! per cycle from the first swing to the last,
//! `1 - (swing_last / swing_first)^(2 / (half-cycles between them))`. The
//! loss is the squared difference to the target.

use std::path::Path;

use pd_mesh::Point;

/// A decay target.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Decay {
    /// Index into the scene's `output.probes`.
    pub probe: usize,
    /// Fraction of the amplitude lost per cycle.
    pub lost_per_cycle: f64,
    /// The unit direction the motion is measured along (`None`: the
    /// coordinate axis of largest variance).
    pub direction: Option<Point>,
}

impl Decay {
    /// Reads a decay description (TOML or JSON by extension), checking its
    /// keys against the scene's `probes` count.
    ///
    /// # Errors
    /// An unreadable file, a missing `[decay]` table, an unknown key, a
    /// `lost_per_cycle` outside (0, 1) or a `probe` out of range, each
    /// naming the file and the key.
    pub(crate) fn read(path: &Path, probes: usize) -> Result<Self, String> {
        let file = path.display();
        let text = std::fs::read_to_string(path).map_err(|e| format!("{file}: {e}"))?;
        let value: serde_json::Value = if path.extension().is_some_and(|e| e == "json") {
            serde_json::from_str(&text).map_err(|e| format!("{file}: {e}"))?
        } else {
            let table: toml::Table = text.parse().map_err(|e| format!("{file}: {e}"))?;
            serde_json::to_value(table).map_err(|e| format!("{file}: {e}"))?
        };
        let decay = value
            .get("decay")
            .and_then(|d| d.as_object())
            .ok_or_else(|| format!("{file}: a decay target needs a [decay] table"))?;
        if let Some(unknown) = decay
            .keys()
            .find(|k| !["probe", "lost_per_cycle", "direction"].contains(&k.as_str()))
        {
            return Err(format!(
                "{file}: decay.{unknown}: unknown key (known: probe, lost_per_cycle, direction)"
            ));
        }
        let direction = match decay.get("direction") {
            None => None,
            Some(v) => {
                let numbers: Option<Vec<f64>> = v
                    .as_array()
                    .map(|a| a.iter().filter_map(serde_json::Value::as_f64).collect());
                match numbers.as_deref() {
                    Some([x, y, z]) if [x, y, z].iter().all(|c| c.is_finite()) => {
                        let d = Point::new(*x, *y, *z);
                        if d.norm() == 0.0 {
                            return Err(format!("{file}: decay.direction: must not be zero"));
                        }
                        Some(d.normalize())
                    }
                    _ => {
                        return Err(format!(
                            "{file}: decay.direction: must be three finite numbers [x, y, z]"
                        ));
                    }
                }
            }
        };
        let lost_per_cycle = decay
            .get("lost_per_cycle")
            .and_then(|v| v.as_f64())
            .ok_or_else(|| format!("{file}: decay.lost_per_cycle: a number is required"))?;
        if !(lost_per_cycle > 0.0 && lost_per_cycle < 1.0) {
            return Err(format!(
                "{file}: decay.lost_per_cycle: must be in (0, 1) (the fraction of the amplitude \
                 lost per cycle), got {lost_per_cycle}"
            ));
        }
        let probe = match decay.get("probe") {
            None => 0,
            Some(v) => v
                .as_u64()
                .map(|p| p as usize)
                .ok_or_else(|| format!("{file}: decay.probe: must be a whole number >= 0"))?,
        };
        if probe >= probes {
            return Err(format!(
                "{file}: decay.probe: {probe} is out of range: the scene's output.probes has \
                 {probes} entries"
            ));
        }
        Ok(Self {
            probe,
            lost_per_cycle,
            direction,
        })
    }
}

/// The mean fraction of amplitude lost per cycle by the trajectory
/// `positions` (one point per step, from step 0) along `direction` (or
/// the coordinate axis of largest variance), or why it cannot be measured
/// (fewer than three extrema: less than one cycle).
pub(crate) fn lost_per_cycle(positions: &[Point], direction: Option<Point>) -> Result<f64, String> {
    let direction = direction.unwrap_or_else(|| {
        let n = positions.len() as f64;
        let mean = positions.iter().sum::<Point>() / n;
        let variance = positions
            .iter()
            .map(|p| (p - mean).component_mul(&(p - mean)))
            .sum::<Point>();
        let mut axis = Point::zeros();
        axis[variance.imax()] = 1.0;
        axis
    });
    let s: Vec<f64> = positions.iter().map(|p| p.dot(&direction)).collect();
    let mut extrema = Vec::new();
    for t in 1..s.len().saturating_sub(1) {
        let (a, b, c) = (s[t - 1], s[t], s[t + 1]);
        if (b > a && b >= c) || (b < a && b <= c) {
            let curvature = a - 2.0 * b + c;
            let refined = if curvature != 0.0 {
                b - (c - a) * (c - a) / (8.0 * curvature)
            } else {
                b
            };
            extrema.push(refined);
        }
    }
    if extrema.len() < 3 {
        return Err(format!(
            "the probe's motion has {} extrema in the run; a decay per cycle needs at least \
             three (one full cycle): run more steps",
            extrema.len()
        ));
    }
    let swings: Vec<f64> = extrema.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    let (first, last) = (swings[0], swings[swings.len() - 1]);
    if !(first > 0.0 && last > 0.0) {
        return Err("the probe does not swing".into());
    }
    let half_cycles = (swings.len() - 1) as f64;
    Ok(1.0 - (last / first).powf(2.0 / half_cycles))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_damped_cosine_loses_its_decay_per_cycle() {
        // x(t) = 0.3 + e^{-zeta omega t} cos(omega_d t) along y, sampled
        // 40 times a cycle: the loss per cycle is 1 - e^{-zeta omega T}.
        let (zeta, omega) = (0.05_f64, 2.0 * std::f64::consts::PI);
        let omega_d = omega * (1.0 - zeta * zeta).sqrt();
        let period = 2.0 * std::f64::consts::PI / omega_d;
        let dt = period / 40.0;
        let positions: Vec<Point> = (0..400)
            .map(|k| {
                let t = k as f64 * dt;
                Point::new(
                    0.01,
                    0.3 + (-zeta * omega * t).exp() * (omega_d * t).cos(),
                    0.0,
                )
            })
            .collect();
        let expected = 1.0 - (-zeta * omega * period).exp();
        let measured = lost_per_cycle(&positions, None).unwrap();
        let along = lost_per_cycle(&positions, Some(Point::new(0.0, 1.0, 0.0))).unwrap();
        assert_eq!(measured, along);
        // The parabola through three samples 1/40 of a cycle apart errs
        // by about (2 pi / 40)^2 / 12 of an extremum's value near its top,
        // and the errors of the first and last swing partly cancel: 1e-3
        // relative.
        assert!(
            (measured / expected - 1.0).abs() < 1e-3,
            "{measured} vs {expected}"
        );
    }

    #[test]
    fn less_than_a_cycle_is_refused() {
        let positions: Vec<Point> = (0..10).map(|k| Point::new(k as f64, 0.0, 0.0)).collect();
        assert!(
            lost_per_cycle(&positions, None)
                .unwrap_err()
                .contains("at least three")
        );
    }
}
