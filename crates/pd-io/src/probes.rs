//! Reading back `probes.csv`, the probe trajectories a run writes
//! ([`crate::recorder`]): `step,time` and `x_I,y_I,z_I,vx_I,vy_I,vz_I` per
//! probed vertex `I`, one row per step from step 0 (the initial state).
//! `pd fit` takes such a file as the motion to match.
//!
//! Every error names the file and its 1-based line.

use std::path::{Path, PathBuf};

use pd_mesh::Point;

use crate::error::{Error, Result};
use crate::lines::{quoted, read_text};

/// Columns per probed vertex: position and velocity.
const COLUMNS_PER_PROBE: usize = 6;

/// One row of a probes file.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeRow {
    /// 1-based line of the file the row is on.
    pub line: usize,
    /// The step (0: the initial state).
    pub step: usize,
    /// Simulated time, s.
    pub time: f64,
    /// Each probe's position, m, in the header's order.
    pub positions: Vec<Point>,
    /// Each probe's velocity, m/s.
    pub velocities: Vec<Point>,
}

/// A whole probes file.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeTrack {
    /// The file it was read from.
    pub path: PathBuf,
    /// The probed vertices, in column order.
    pub probes: Vec<usize>,
    /// The rows, in file order (steps consecutive from the first).
    pub rows: Vec<ProbeRow>,
}

impl ProbeTrack {
    /// Reads a probes file as `pd run` writes it.
    ///
    /// # Errors
    /// The file cannot be read ([`Error::Io`]); the header is not
    /// `step,time` followed by the six columns of each probe; a row has the
    /// wrong number of fields, a field that is not a (finite) number, or a
    /// step out of sequence; there is no row ([`Error::Parse`] with the
    /// line).
    pub fn read(path: &Path) -> Result<Self> {
        let text = read_text(path)?;
        let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
        let error = |line: usize, message: String| Error::Parse {
            path: path.to_path_buf(),
            line,
            message,
        };
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim()))
            .filter(|(_, l)| !l.is_empty());
        let Some((header_line, header)) = lines.next() else {
            return Err(error(
                1,
                "the file is empty: expected the header `step,time,x_I,y_I,z_I,vx_I,vy_I,vz_I,...`"
                    .into(),
            ));
        };
        let probes = parse_header(header).map_err(|m| error(header_line, m))?;
        let fields = 2 + COLUMNS_PER_PROBE * probes.len();
        let mut rows: Vec<ProbeRow> = Vec::new();
        for (line, text) in lines {
            let values: Vec<&str> = text.split(',').map(str::trim).collect();
            if values.len() != fields {
                return Err(error(
                    line,
                    format!(
                        "expected {fields} fields (step, time and 6 per probe for {} probes), \
                         found {}",
                        probes.len(),
                        values.len()
                    ),
                ));
            }
            let step: usize = values[0].parse().map_err(|_| {
                error(
                    line,
                    format!(
                        "the step must be a non-negative integer, found {}",
                        quoted(values[0])
                    ),
                )
            })?;
            if let Some(previous) = rows.last()
                && step != previous.step + 1
            {
                return Err(error(
                    line,
                    format!(
                        "step {step} out of sequence: expected {} (rows must be consecutive \
                         steps)",
                        previous.step + 1
                    ),
                ));
            }
            let mut numbers = Vec::with_capacity(fields - 1);
            for (column, value) in values.iter().enumerate().skip(1) {
                let number: f64 = value
                    .parse()
                    .ok()
                    .filter(|v: &f64| v.is_finite())
                    .ok_or_else(|| {
                        error(
                            line,
                            format!(
                                "column {} must be a finite number, found {}",
                                column + 1,
                                quoted(value)
                            ),
                        )
                    })?;
                numbers.push(number);
            }
            let point =
                |start: usize| Point::new(numbers[start], numbers[start + 1], numbers[start + 2]);
            let (positions, velocities) = (0..probes.len())
                .map(|p| {
                    let start = 1 + COLUMNS_PER_PROBE * p;
                    (point(start), point(start + 3))
                })
                .unzip();
            rows.push(ProbeRow {
                line,
                step,
                time: numbers[0],
                positions,
                velocities,
            });
        }
        if rows.is_empty() {
            return Err(error(
                header_line,
                "the file has a header but no rows".into(),
            ));
        }
        Ok(Self {
            path: path.to_path_buf(),
            probes,
            rows,
        })
    }
}

/// The probed vertices of a header `step,time,x_I,y_I,z_I,vx_I,vy_I,vz_I,...`.
fn parse_header(header: &str) -> std::result::Result<Vec<usize>, String> {
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    if names.len() < 2 || names[0] != "step" || names[1] != "time" {
        return Err(format!(
            "the header must start with `step,time`, found {}",
            quoted(header)
        ));
    }
    let columns = &names[2..];
    if columns.is_empty() || !columns.len().is_multiple_of(COLUMNS_PER_PROBE) {
        return Err(format!(
            "the header must have 6 columns per probe (x_I,y_I,z_I,vx_I,vy_I,vz_I) after \
             `step,time`, found {} columns",
            columns.len()
        ));
    }
    columns
        .chunks(COLUMNS_PER_PROBE)
        .map(|group| {
            let vertex = group[0]
                .strip_prefix("x_")
                .and_then(|v| v.parse::<usize>().ok())
                .ok_or_else(|| {
                    format!(
                        "expected a column `x_I` (I a vertex), found {}",
                        quoted(group[0])
                    )
                })?;
            for (name, prefix) in group.iter().zip(["x", "y", "z", "vx", "vy", "vz"]) {
                if *name != format!("{prefix}_{vertex}") {
                    return Err(format!(
                        "expected the column `{prefix}_{vertex}`, found {}",
                        quoted(name)
                    ));
                }
            }
            Ok(vertex)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(name: &str, text: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("pd-io-probes-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn a_file_as_the_recorder_writes_it_reads_back() {
        let path = write(
            "good.csv",
            "step,time,x_4,y_4,z_4,vx_4,vy_4,vz_4\n0,0,1,2,3,0,0,0\n1,0.01,1,1.5,3,0,-50,0\n",
        );
        let track = ProbeTrack::read(&path).unwrap();
        assert_eq!(track.probes, vec![4]);
        assert_eq!(track.rows.len(), 2);
        assert_eq!(track.rows[1].line, 3);
        assert_eq!(track.rows[1].step, 1);
        assert_eq!(track.rows[1].positions[0], Point::new(1.0, 1.5, 3.0));
        assert_eq!(track.rows[1].velocities[0], Point::new(0.0, -50.0, 0.0));
    }

    #[test]
    fn malformed_files_are_refused_at_their_line() {
        let cases = [
            ("empty.csv", "", ":1: the file is empty"),
            ("header.csv", "step,t,x_1\n", ":1: the header must start"),
            (
                "columns.csv",
                "step,time,x_1,y_1\n",
                ":1: the header must have 6 columns",
            ),
            (
                "names.csv",
                "step,time,x_1,y_1,z_2,vx_1,vy_1,vz_1\n",
                "expected the column `z_1`",
            ),
            (
                "fields.csv",
                "step,time,x_1,y_1,z_1,vx_1,vy_1,vz_1\n0,0,1,2,3,4,5,6\n1,0.1,1,2\n",
                ":3: expected 8 fields",
            ),
            (
                "number.csv",
                "step,time,x_1,y_1,z_1,vx_1,vy_1,vz_1\n0,0,1,2,nan,4,5,6\n",
                ":2: column 5 must be a finite number",
            ),
            (
                "sequence.csv",
                "step,time,x_1,y_1,z_1,vx_1,vy_1,vz_1\n0,0,1,2,3,4,5,6\n2,0,1,2,3,4,5,6\n",
                ":3: step 2 out of sequence",
            ),
            (
                "rows.csv",
                "step,time,x_1,y_1,z_1,vx_1,vy_1,vz_1\n",
                ":1: the file has a header but no rows",
            ),
        ];
        for (name, text, expected) in cases {
            let err = ProbeTrack::read(&write(name, text))
                .unwrap_err()
                .to_string();
            assert!(
                err.contains(name) && err.contains(expected),
                "{name}: {err}"
            );
        }
    }
}
