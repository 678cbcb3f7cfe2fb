//! Command-line options as `--name value` pairs and flags, shared by
//! `pd-probe` and the examples of `benches/examples/`.

/// The arguments of a command, read as `--name value` pairs and flags.
#[derive(Debug, Clone, Copy)]
pub struct Options<'a> {
    args: &'a [String],
}

impl<'a> Options<'a> {
    /// Options over `args` (the program name excluded).
    pub fn new(args: &'a [String]) -> Self {
        Self { args }
    }

    /// The value after `name`, if `name` is given.
    pub fn value(&self, name: &str) -> Option<&'a str> {
        self.args
            .iter()
            .position(|a| a == name)
            .and_then(|i| self.args.get(i + 1))
            .map(String::as_str)
    }

    /// Whether the flag `name` is given.
    pub fn flag(&self, name: &str) -> bool {
        self.args.iter().any(|a| a == name)
    }

    /// The value after `name` parsed, or `default` without `name`.
    ///
    /// # Errors
    /// A value that does not parse, naming the option.
    pub fn parse<T: std::str::FromStr>(&self, name: &str, default: T) -> Result<T, String> {
        match self.value(name) {
            None => Ok(default),
            Some(text) => text
                .parse()
                .map_err(|_| format!("{name}: cannot parse {text:?}")),
        }
    }

    /// Chebyshev's `rho` after `name`: a number or `auto` (also without
    /// `name`).
    ///
    /// # Errors
    /// A value that is neither, naming the option.
    pub fn spectral_radius(&self, name: &str) -> Result<pd_solver::SpectralRadius, String> {
        match self.value(name) {
            None | Some("auto") => Ok(pd_solver::SpectralRadius::Auto),
            Some(_) => self.parse(name, 0.0).map(pd_solver::SpectralRadius::Fixed),
        }
    }

    /// Checks that every argument spelled as an option (`--name`) is one
    /// of `known`, so that a typo stops the program instead of running it
    /// with the default.
    ///
    /// # Errors
    /// The first unknown option, named.
    pub fn only(&self, known: &[&str]) -> Result<(), String> {
        match self
            .args
            .iter()
            .find(|a| a.starts_with("--") && !known.contains(&a.as_str()))
        {
            Some(unknown) => Err(format!("unknown option {unknown}")),
            None => Ok(()),
        }
    }

    /// The comma-separated values (counts, numbers) after `name`, or
    /// `default` without `name`.
    ///
    /// # Errors
    /// An entry that does not parse, naming the option.
    pub fn list<T: std::str::FromStr + Clone>(
        &self,
        name: &str,
        default: &[T],
    ) -> Result<Vec<T>, String> {
        match self.value(name) {
            None => Ok(default.to_vec()),
            Some(text) => text
                .split(',')
                .map(|p| {
                    p.trim()
                        .parse()
                        .map_err(|_| format!("{name}: cannot parse {p:?} in {text:?}"))
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_flags_and_lists_are_read() {
        let args: Vec<String> = ["step", "--cells", "4, 2,2", "--dt", "0.5", "--quiet"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let options = Options::new(&args);
        assert_eq!(
            options.list::<usize>("--cells", &[]).unwrap(),
            vec![4, 2, 2]
        );
        assert_eq!(options.parse("--dt", 1.0).unwrap(), 0.5);
        assert_eq!(options.parse("--steps", 7).unwrap(), 7);
        assert!(options.flag("--quiet") && !options.flag("--loud"));
        assert!(options.only(&["--cells", "--dt", "--quiet"]).is_ok());
        assert_eq!(
            options.only(&["--cells", "--quiet"]).unwrap_err(),
            "unknown option --dt"
        );
        assert!(
            options
                .parse::<usize>("--dt", 1)
                .unwrap_err()
                .contains("--dt")
        );
        assert!(options.list::<usize>("--dt", &[]).is_err());
        assert_eq!(options.list("--dt", &[1.0]).unwrap(), vec![0.5]);
        assert_eq!(options.list("--targets", &[0.01]).unwrap(), vec![0.01]);
    }
}
