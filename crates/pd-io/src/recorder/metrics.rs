//! `metrics.csv`, owned by one type: [`MetricsRow`] makes a row from the
//! simulation, writes the header and the rows, and reads a file back, so
//! the recorder, `pd resume`, `pd plot` and `pd compare` agree on the format
//! by construction.
//!
//! The columns are declared once, in the `metrics_columns!` invocation
//! below: a column's field, type, doc and text format. Adding a column is
//! one line there plus the value in [`MetricsRow::of`]; the header, the
//! writer and the reader follow. Readers refuse a file whose header is not
//! this version's, rather than misread its columns.

use std::io::{self, Write};
use std::path::Path;

use pd_mesh::Point;
use pd_solver::{Simulation, StepStats};

use crate::{Error, Result};

/// Declares [`MetricsRow`] with one field per column, in file order, and
/// its column names and text form. Each column: doc comment, `field: type`,
/// and the format its value is written with.
macro_rules! metrics_columns {
    ($($(#[doc = $doc:literal])+ $field:ident: $ty:ty => $format:literal,)+) => {
        /// One row of `metrics.csv`: the state after a step (row 0: the
        /// initial state). Energies in J, linear momentum in kg m/s,
        /// angular momentum about the origin in kg m^2/s, times in ms.
        #[derive(Debug, Clone, Copy, PartialEq, Default)]
        pub struct MetricsRow {
            $($(#[doc = $doc])+ pub $field: $ty,)+
        }

        impl MetricsRow {
            /// The column names, in file order: the header's fields.
            pub const COLUMNS: &'static [&'static str] = &[$(stringify!($field)),+];

            /// Writes the row's fields, comma separated, and the newline.
            #[allow(unused_assignments)] // the separator after the last field
            fn write_fields(&self, w: &mut dyn Write) -> io::Result<()> {
                let mut separator = "";
                $(
                    w.write_all(separator.as_bytes())?;
                    write!(w, $format, self.$field)?;
                    separator = ",";
                )+
                writeln!(w)
            }

            /// The row of `fields`, if there are exactly as many as
            /// columns and each parses.
            fn from_fields<'a>(mut fields: impl Iterator<Item = &'a str>) -> Option<Self> {
                let row = Self {
                    $($field: fields.next()?.parse().ok()?,)+
                };
                fields.next().is_none().then_some(row)
            }
        }
    };
}

metrics_columns! {
    /// Step number (0: the initial state).
    step: usize => "{}",
    /// Simulated time, s.
    time: f64 => "{}",
    /// Kinetic energy, J.
    kinetic: f64 => "{}",
    /// Elastic (constraint) energy, J.
    elastic: f64 => "{}",
    /// Gravitational potential energy, J.
    gravity: f64 => "{}",
    /// Kinetic + elastic + gravitational energy, J.
    total: f64 => "{}",
    /// Linear momentum, x, kg m/s.
    px: f64 => "{}",
    /// Linear momentum, y, kg m/s.
    py: f64 => "{}",
    /// Linear momentum, z, kg m/s.
    pz: f64 => "{}",
    /// Angular momentum about the origin, x, kg m^2/s.
    jx: f64 => "{}",
    /// Angular momentum about the origin, y, kg m^2/s.
    jy: f64 => "{}",
    /// Angular momentum about the origin, z, kg m^2/s.
    jz: f64 => "{}",
    /// Local-global iterations the step took (0 in row 0).
    iterations: usize => "{}",
    /// Wall time of the step, ms (0 in row 0).
    step_ms: f64 => "{:.4}",
    /// Wall time of its local steps, ms.
    local_ms: f64 => "{:.4}",
    /// Wall time of its global steps, ms.
    global_ms: f64 => "{:.4}",
    /// The step's final relative residual `|G(x) - x|_M / |G(x) - x_n|_M`
    /// (docs/design/solver.md; 0 in row 0).
    residual: f64 => "{}",
    /// The step's estimated relative error: the estimated fraction of the
    /// step's correction `y -> x*` left undone, in the mass norm
    /// (docs/design/solver.md, "How far from converged"; 0 in row 0).
    estimated_error: f64 => "{}",
    /// Contacts active at the end of the step (0 without colliders).
    contacts: usize => "{}",
    /// Deepest penetration into a collider thickened by the contact thickness, m.
    penetration: f64 => "{}",
}

impl MetricsRow {
    /// The file's name in a run's output folder.
    pub const FILE: &'static str = "metrics.csv";

    /// The row of `sim`'s current state; `stats` of the step just taken
    /// (`None` for the initial state: zero iterations and timings).
    pub fn of(sim: &Simulation, stats: Option<&StepStats>) -> Self {
        let e = sim.energies();
        let p = sim.linear_momentum();
        let j = sim.angular_momentum();
        let (iterations, step_ms, local_ms, global_ms) = stats.map_or((0, 0.0, 0.0, 0.0), |s| {
            (
                s.iterations,
                s.total_seconds * 1e3,
                s.local_seconds * 1e3,
                s.global_seconds * 1e3,
            )
        });
        Self {
            step: sim.steps(),
            time: sim.time(),
            kinetic: e.kinetic,
            elastic: e.elastic,
            gravity: e.gravity,
            total: e.total(),
            px: p.x,
            py: p.y,
            pz: p.z,
            jx: j.x,
            jy: j.y,
            jz: j.z,
            iterations,
            step_ms,
            local_ms,
            global_ms,
            residual: stats.map_or(0.0, |s| s.relative_change),
            estimated_error: stats.map_or(0.0, |s| s.estimated_error),
            contacts: stats.map_or(0, |s| s.contacts),
            penetration: stats.map_or(0.0, |s| s.penetration),
        }
    }

    /// The header line, without its newline.
    pub fn header() -> String {
        Self::COLUMNS.join(",")
    }

    /// Writes the header line.
    ///
    /// # Errors
    /// What `w` returns.
    pub fn write_header(w: &mut dyn Write) -> io::Result<()> {
        writeln!(w, "{}", Self::header())
    }

    /// Writes the row as one line. Floats are written so that they parse
    /// back to the same bits, except the timings (4 decimals).
    ///
    /// # Errors
    /// What `w` returns.
    pub fn write(&self, w: &mut dyn Write) -> io::Result<()> {
        self.write_fields(w)
    }

    /// The row a line of the file holds, if it has one number per column.
    pub fn parse(line: &str) -> Option<Self> {
        Self::from_fields(line.split(','))
    }

    /// Linear momentum, kg m/s.
    pub fn linear_momentum(&self) -> Point {
        Point::new(self.px, self.py, self.pz)
    }

    /// Angular momentum about the origin, kg m^2/s.
    pub fn angular_momentum(&self) -> Point {
        Point::new(self.jx, self.jy, self.jz)
    }

    /// Reads every row of the file at `path`.
    ///
    /// # Errors
    /// [`Error::Io`]; [`Error::Parse`] at line 1 for a header other than
    /// [`MetricsRow::header`], or at the line of a row that does not hold
    /// one number per column; [`Error::Content`] for a file without a
    /// header or without rows.
    pub fn read_all(path: &Path) -> Result<Vec<Self>> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::parse_all(&text, path)
    }

    /// [`MetricsRow::read_all`] of the text `text` of `path`.
    pub(crate) fn parse_all(text: &str, path: &Path) -> Result<Vec<Self>> {
        let parse_error = |line: usize, message: String| Error::Parse {
            path: path.to_path_buf(),
            line,
            message,
        };
        let mut lines = text.lines();
        let header = lines.next().ok_or_else(|| Error::Content {
            path: path.to_path_buf(),
            message: "empty file".into(),
        })?;
        if header != Self::header() {
            return Err(parse_error(
                1,
                format!("expected the header `{}`", Self::header()),
            ));
        }
        let rows = lines
            .enumerate()
            .map(|(i, line)| {
                Self::parse(line).ok_or_else(|| {
                    parse_error(i + 2, format!("expected {} numbers", Self::COLUMNS.len()))
                })
            })
            .collect::<Result<Vec<_>>>()?;
        if rows.is_empty() {
            return Err(Error::Content {
                path: path.to_path_buf(),
                message: "no rows".into(),
            });
        }
        Ok(rows)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_round_trip_through_their_text() {
        let row = MetricsRow {
            step: 3,
            time: 0.030000000000000002,
            kinetic: 1.0 / 3.0,
            total: -2.5e-300,
            jz: f64::MAX,
            iterations: 10,
            step_ms: 1.23456,
            residual: 3.7e-7,
            estimated_error: 0.0123,
            ..MetricsRow::default()
        };
        let mut text = Vec::new();
        MetricsRow::write_header(&mut text).unwrap();
        row.write(&mut text).unwrap();
        let text = String::from_utf8(text).unwrap();
        assert_eq!(
            text.lines().next(),
            Some(
                "step,time,kinetic,elastic,gravity,total,px,py,pz,jx,jy,jz,iterations,\
                 step_ms,local_ms,global_ms,residual,estimated_error,contacts,penetration"
            )
        );
        let back = MetricsRow::parse_all(&text, Path::new("metrics.csv")).unwrap();
        // Everything comes back bit for bit but the timings, written with 4
        // decimals.
        assert_eq!(
            back,
            [MetricsRow {
                step_ms: 1.2346,
                ..row
            }]
        );
    }

    #[test]
    fn malformed_files_name_the_line() {
        let path = Path::new("metrics.csv");
        let header = MetricsRow::header();
        let error = |text: &str| MetricsRow::parse_all(text, path).unwrap_err().to_string();
        assert_eq!(error(""), "metrics.csv: empty file");
        assert_eq!(error(&format!("{header}\n")), "metrics.csv: no rows");
        assert!(error("step,time\n0,0\n").starts_with("metrics.csv:1: expected the header"));
        let short = format!("{header}\n0,0,0\n");
        assert_eq!(error(&short), "metrics.csv:2: expected 20 numbers");
        let long = format!("{header}\n{}\n", ["0"; 21].join(","));
        assert_eq!(error(&long), "metrics.csv:2: expected 20 numbers");
        let word = format!(
            "{header}\n{}\nzero{}\n",
            ["0"; 20].join(","),
            ",0".repeat(19)
        );
        assert_eq!(error(&word), "metrics.csv:3: expected 20 numbers");
    }
}
