//! Splitting the stability matrix over machines.
//!
//! `cargo xtask stability [--quick] --shard I/N [--out DIR]` runs the cases
//! whose index is `I mod N` (strided, so every shard gets a similar mix of
//! cheap and expensive cases) and writes their endings to
//! `DIR/stability-shard-I-of-N.json` (default `DIR`:
//! `target/stability-shards`). `cargo xtask stability [--quick] --merge DIR`
//! reads every `stability-shard-*.json` in `DIR`, checks that together they
//! cover the matrix exactly once (same `--quick`, same matrix size), and
//! writes `docs/reports/stability.md` as a single run would. docs/reference/cli.md shows a
//! batch-system recipe.

use std::path::{Path, PathBuf};

use pd_io::recorder::EnergyCreated;
use serde_json::{Value, json};

use super::Ending;

/// What this invocation does with the matrix.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Mode {
    /// Every case, then the report.
    Whole,
    /// Cases `index mod count == shard`, written to `out`.
    Shard {
        shard: usize,
        count: usize,
        out: PathBuf,
    },
    /// No case: the report from the shard files in this folder.
    Merge(PathBuf),
}

impl Mode {
    /// Parses `--shard I/N`, `--out DIR` and `--merge DIR` from `args`.
    pub fn parse(root: &Path, args: &[String]) -> Result<Self, String> {
        let value = |name: &str| -> Result<Option<&String>, String> {
            match args.iter().position(|a| a == name) {
                None => Ok(None),
                Some(i) => args
                    .get(i + 1)
                    .map(Some)
                    .ok_or_else(|| format!("{name} needs a value")),
            }
        };
        match (value("--shard")?, value("--merge")?) {
            (Some(_), Some(_)) => Err("--shard and --merge exclude each other".into()),
            (None, Some(dir)) => Ok(Self::Merge(PathBuf::from(dir))),
            (None, None) => Ok(Self::Whole),
            (Some(text), None) => {
                let parsed = text
                    .split_once('/')
                    .and_then(|(i, n)| Some((i.parse().ok()?, n.parse().ok()?)));
                let Some((shard, count)) = parsed.filter(|&(i, n): &(usize, usize)| i < n) else {
                    return Err(format!("--shard {text}: expected I/N with 0 <= I < N"));
                };
                let out = value("--out")?
                    .map_or_else(|| root.join("target/stability-shards"), PathBuf::from);
                Ok(Self::Shard { shard, count, out })
            }
        }
    }

    /// Whether case `index` runs here.
    pub fn runs(&self, index: usize) -> bool {
        match self {
            Self::Whole => true,
            Self::Shard { shard, count, .. } => index % count == *shard,
            Self::Merge(_) => false,
        }
    }
}

fn ending_to_json(ending: &Ending) -> Value {
    match ending {
        Ending::Completed {
            rise,
            inverted,
            energy,
        } => {
            let energy = energy.map(|e| json!([e.created, e.largest]));
            json!({ "completed": rise, "inverted": inverted, "energy_created": energy })
        }
        Ending::Diverged { step, reason } => {
            json!({ "diverged": { "step": step, "reason": reason } })
        }
        Ending::Bug(message) => json!({ "bug": message }),
    }
}

fn ending_from_json(value: &Value) -> Option<Ending> {
    if let Some(rise) = value.get("completed") {
        // `[created, largest]` in J, or null where the rule does not apply;
        // a file without the field (an older xtask's) is refused.
        let energy = match value.get("energy_created")? {
            Value::Null => None,
            pair => Some(EnergyCreated {
                created: pair.get(0)?.as_f64()?,
                largest: pair.get(1)?.as_f64()?,
            }),
        };
        return Some(Ending::Completed {
            rise: rise.as_f64()?,
            inverted: usize::try_from(value.get("inverted")?.as_u64()?).ok()?,
            energy,
        });
    }
    if let Some(diverged) = value.get("diverged") {
        return Some(Ending::Diverged {
            step: usize::try_from(diverged.get("step")?.as_u64()?).ok()?,
            reason: diverged.get("reason")?.as_str()?.to_string(),
        });
    }
    Some(Ending::Bug(value.get("bug")?.as_str()?.to_string()))
}

/// Writes one shard's endings; returns the file written.
pub fn write(
    mode: &Mode,
    quick: bool,
    total: usize,
    seconds: f64,
    results: &[(usize, Ending)],
) -> Result<PathBuf, String> {
    let Mode::Shard { shard, count, out } = mode else {
        return Err("not a shard run".into());
    };
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let path = out.join(format!("stability-shard-{shard}-of-{count}.json"));
    let document = json!({
        "quick": quick,
        "cases": total,
        "shard": shard,
        "shards": count,
        "seconds": seconds,
        "results": results
            .iter()
            .map(|(index, ending)| json!([index, ending_to_json(ending)]))
            .collect::<Vec<_>>(),
    });
    std::fs::write(&path, document.to_string()).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(path)
}

/// Reads every shard file in `dir`: the endings by case index (sorted) and
/// the shards' summed run time in seconds.
pub fn read(dir: &Path, quick: bool, total: usize) -> Result<(Vec<(usize, Ending)>, f64), String> {
    let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut paths: Vec<PathBuf> = entries
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("stability-shard-") && n.ends_with(".json"))
        })
        .collect();
    paths.sort();
    let mut slots: Vec<Option<Ending>> = vec![None; total];
    let mut seconds = 0.0;
    for path in &paths {
        let name = path.display();
        let text = std::fs::read_to_string(path).map_err(|e| format!("{name}: {e}"))?;
        let document: Value =
            serde_json::from_str(&text).map_err(|e| format!("{name}: not JSON: {e}"))?;
        if document["quick"].as_bool() != Some(quick)
            || document["cases"].as_u64() != Some(total as u64)
        {
            return Err(format!(
                "{name}: a different matrix (quick {}, {} cases; this run: quick {quick}, {total})",
                document["quick"], document["cases"]
            ));
        }
        seconds += document["seconds"].as_f64().unwrap_or(0.0);
        let results = document["results"]
            .as_array()
            .ok_or_else(|| format!("{name}: field `results` is not a list"))?;
        for (k, entry) in results.iter().enumerate() {
            let bad = || format!("{name}: results[{k}] is not [index, ending]");
            let index = entry[0].as_u64().and_then(|i| usize::try_from(i).ok());
            let index = index.filter(|&i| i < total).ok_or_else(bad)?;
            let ending = ending_from_json(&entry[1]).ok_or_else(bad)?;
            if slots[index].replace(ending).is_some() {
                return Err(format!("{name}: case {index} appears in two shards"));
            }
        }
    }
    let missing = slots.iter().filter(|s| s.is_none()).count();
    if missing > 0 {
        return Err(format!(
            "{}: {missing} of {total} cases are in no shard file ({} files read)",
            dir.display(),
            paths.len()
        ));
    }
    let results = slots
        .into_iter()
        .enumerate()
        .filter_map(|(i, s)| s.map(|e| (i, e)))
        .collect();
    Ok((results, seconds))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::strings;

    #[test]
    fn shard_arguments_parse_and_reject_nonsense() {
        let root = Path::new("/r");
        assert_eq!(
            Mode::parse(root, &strings(&["--quick"])).unwrap(),
            Mode::Whole
        );
        assert_eq!(
            Mode::parse(root, &strings(&["--shard", "1/3"])).unwrap(),
            Mode::Shard {
                shard: 1,
                count: 3,
                out: PathBuf::from("/r/target/stability-shards")
            }
        );
        for bad in [["--shard", "3/3"], ["--shard", "x/2"], ["--shard", "1"]] {
            assert!(Mode::parse(root, &strings(&bad)).is_err(), "{bad:?}");
        }
        assert!(Mode::parse(root, &strings(&["--shard", "0/2", "--merge", "d"])).is_err());
    }

    #[test]
    fn shards_written_then_merged_give_back_every_ending() {
        let dir = std::env::temp_dir().join(format!("pd-shards-{}", std::process::id()));
        let endings = [
            Ending::Completed {
                rise: 0.1 + 0.2,
                inverted: 3,
                energy: Some(EnergyCreated {
                    created: 0.1 + 0.7,
                    largest: 1e-300,
                }),
            },
            Ending::Diverged {
                step: 7,
                reason: "energy".into(),
            },
            Ending::Bug("panic: x".into()),
            Ending::Completed {
                rise: 0.0,
                inverted: 0,
                energy: None,
            },
            Ending::Completed {
                rise: 1e-300,
                inverted: 0,
                energy: Some(EnergyCreated {
                    created: 0.0,
                    largest: 2.5,
                }),
            },
        ];
        let total = endings.len();
        for shard in 0..2 {
            let mode = Mode::Shard {
                shard,
                count: 2,
                out: dir.clone(),
            };
            let mine: Vec<(usize, Ending)> = (0..total)
                .filter(|&i| mode.runs(i))
                .map(|i| (i, endings[i].clone()))
                .collect();
            write(&mode, true, total, 1.5, &mine).unwrap();
        }
        let (merged, seconds) = read(&dir, true, total).unwrap();
        assert_eq!(seconds, 3.0);
        let expected: Vec<(usize, Ending)> = endings.iter().cloned().enumerate().collect();
        assert_eq!(merged, expected);
        // A different matrix, or a missing shard, is refused.
        assert!(read(&dir, false, total).is_err());
        std::fs::remove_file(dir.join("stability-shard-1-of-2.json")).unwrap();
        assert!(read(&dir, true, total).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
