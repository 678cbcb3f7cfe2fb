//! The line tokenizer every text mesh reader uses (TetGen, Gmsh, Medit,
//! OBJ): a file read as UTF-8 with invalid bytes reported at their line,
//! split into non-blank lines with `#` comments stripped, each split into
//! whitespace-separated fields, with typed field parsers whose errors name
//! the file, the 1-based line and what the field is.
//!
//! Counted sections (a header declaring how many data lines follow, as
//! TetGen's files have) are read with [`DataLines::header`],
//! [`DataLines::data_line`] and [`DataLines::expect_end`].
//!
//! A leading UTF-8 byte order mark (as some Windows editors write) is
//! skipped. Text from the file is quoted in messages with [`quoted`], which
//! shortens a long token so that one malformed line cannot flood the
//! terminal.

use std::fmt;
use std::path::Path;
use std::str::FromStr;

use crate::error::{Error, Result};

/// Reads a whole file as UTF-8, reporting invalid bytes at their line.
pub(crate) fn read_text(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).map_err(|source| Error::io(path, source))?;
    String::from_utf8(bytes).map_err(|err| {
        let valid = &err.as_bytes()[..err.utf8_error().valid_up_to()];
        Error::Parse {
            path: path.to_path_buf(),
            line: 1 + valid.iter().filter(|&&b| b == b'\n').count(),
            message: "the file is not valid UTF-8 text".into(),
        }
    })
}

/// The non-blank lines of a file, comments stripped, split into fields.
pub(crate) struct DataLines<'a> {
    path: &'a Path,
    lines: std::iter::Enumerate<std::str::Lines<'a>>,
    /// Number of the last line of the file (1 for an empty file), where a
    /// truncated file is reported.
    last_line: usize,
}

/// One non-blank line: its 1-based number and its fields.
pub(crate) struct Line<'a> {
    path: &'a Path,
    pub(crate) line: usize,
    pub(crate) fields: Vec<&'a str>,
}

impl<'a> DataLines<'a> {
    pub(crate) fn new(path: &'a Path, text: &'a str) -> Self {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        Self {
            path,
            lines: text.lines().enumerate(),
            last_line: text.lines().count().max(1),
        }
    }

    pub(crate) fn next_line(&mut self) -> Option<Line<'a>> {
        for (number, text) in self.lines.by_ref() {
            let data = text.split_once('#').map_or(text, |(data, _comment)| data);
            let fields: Vec<&str> = data.split_whitespace().collect();
            if !fields.is_empty() {
                return Some(Line {
                    path: self.path,
                    line: number + 1,
                    fields,
                });
            }
        }
        None
    }

    pub(crate) fn error_at_end(&self, message: String) -> Error {
        Error::Parse {
            path: self.path.to_path_buf(),
            line: self.last_line,
            message,
        }
    }

    /// The header line, which must have exactly `num_fields` fields.
    pub(crate) fn header(&mut self, layout: &str, num_fields: usize) -> Result<Line<'a>> {
        let header = self.next_line().ok_or_else(|| {
            self.error_at_end(format!("the header is missing: expected `{layout}`"))
        })?;
        if header.fields.len() != num_fields {
            return Err(header.error(format!(
                "the header must have {num_fields} fields `{layout}`, found {}",
                header.fields.len()
            )));
        }
        Ok(header)
    }

    /// Data line number `position` (0-based) of `count` declared on line
    /// `header_line`.
    pub(crate) fn data_line(
        &mut self,
        header_line: usize,
        position: usize,
        count: usize,
        what: &str,
    ) -> Result<Line<'a>> {
        self.next_line().ok_or_else(|| {
            self.error_at_end(format!(
                "the file is truncated: the header on line {header_line} declares {count} \
                 {what} lines, found {position}"
            ))
        })
    }

    /// Fails if any data is left after the `count` declared lines.
    pub(crate) fn expect_end(
        &mut self,
        header_line: usize,
        count: usize,
        what: &str,
    ) -> Result<()> {
        match self.next_line() {
            Some(extra) => Err(extra.error(format!(
                "unexpected data after the {count} {what} declared by the header on line \
                 {header_line}"
            ))),
            None => Ok(()),
        }
    }
}

impl Line<'_> {
    pub(crate) fn error(&self, message: String) -> Error {
        Error::Parse {
            path: self.path.to_path_buf(),
            line: self.line,
            message,
        }
    }

    pub(crate) fn expect_fields(&self, count: usize, layout: &str) -> Result<()> {
        if self.fields.len() == count {
            Ok(())
        } else {
            Err(self.error(format!(
                "expected {count} fields ({layout}), found {}",
                self.fields.len()
            )))
        }
    }

    /// The index in the first field of data line `position` (0-based) of a
    /// `what` section: the first line's index, 0 or 1, is stored in
    /// `first_index`, and the others must follow it consecutively.
    pub(crate) fn sequence_index(
        &self,
        position: usize,
        first_index: &mut usize,
        what: &str,
    ) -> Result<usize> {
        let index = self.unsigned(0, &format!("{what} index"))?;
        if position == 0 {
            if index > 1 {
                return Err(self.error(format!(
                    "{what} indices must start at 0 or 1, found {index}"
                )));
            }
            *first_index = index;
        } else if index != *first_index + position {
            return Err(self.error(format!(
                "{what} index {index} out of sequence: expected {} (indices must be \
                 consecutive)",
                *first_index + position
            )));
        }
        Ok(index)
    }

    /// Field `index` as a count or an index. Integers must be written as
    /// integers (`3`, not `3.0`), as TetGen writes them.
    pub(crate) fn unsigned(&self, index: usize, what: &str) -> Result<usize> {
        let value = self.parse(index, what, "a non-negative integer");
        let text = self.text(index);
        if value.is_err() && !text.is_empty() && text.bytes().all(|b| b.is_ascii_digit()) {
            return Err(self.error(format!("the {what} {} is too large", quoted(text))));
        }
        value
    }

    /// Field `index` as a signed integer (boundary markers may be negative).
    pub(crate) fn signed(&self, index: usize, what: &str) -> Result<i64> {
        let value = self.parse(index, what, "an integer");
        let text = self.text(index);
        let digits = text.strip_prefix(['-', '+']).unwrap_or(text);
        if value.is_err() && !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit()) {
            return Err(self.error(format!(
                "the {what} {} is out of range (a 64-bit integer)",
                quoted(text)
            )));
        }
        value
    }

    /// Field `index` as a number; `inf` and `nan` parse, so callers that
    /// need finite values check them.
    pub(crate) fn number(&self, index: usize, what: &str) -> Result<f64> {
        self.parse(index, what, "a number")
    }

    /// The text of field `index`, empty if there is no such field.
    pub(crate) fn text(&self, index: usize) -> &str {
        self.fields.get(index).copied().unwrap_or_default()
    }

    fn parse<T: FromStr>(&self, index: usize, what: &str, expected: &str) -> Result<T> {
        let text = self.text(index);
        text.parse().map_err(|_| {
            self.error(format!(
                "the {what} must be {expected}, found {}",
                quoted(text)
            ))
        })
    }
}

/// Longest text, in characters, that [`quoted`] shows whole.
const QUOTE_LIMIT: usize = 60;

/// Text from a file, for a message: in backticks, and if longer than
/// [`QUOTE_LIMIT`] characters cut there with an ellipsis and its length
/// (`` `1234…` (10000000 characters) ``).
pub(crate) fn quoted(text: &str) -> Quoted<'_> {
    Quoted(text)
}

/// See [`quoted`].
pub(crate) struct Quoted<'a>(&'a str);

impl fmt::Display for Quoted<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0.char_indices().nth(QUOTE_LIMIT) {
            None => write!(f, "`{}`", self.0),
            Some((cut, _)) => write!(
                f,
                "`{}…` ({} characters)",
                &self.0[..cut],
                self.0.chars().count()
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn comments_and_blank_lines_are_skipped_and_lines_numbered_from_one() {
        let text = "# header comment\n\n  3 4 0 # trailing\n\t\n1 2 3 4 5#x\n#\n";
        let mut lines = DataLines::new(Path::new("t.ele"), text);
        let first = lines.next_line().unwrap();
        assert_eq!((first.line, first.fields), (3, vec!["3", "4", "0"]));
        let second = lines.next_line().unwrap();
        assert_eq!(
            (second.line, second.fields),
            (5, vec!["1", "2", "3", "4", "5"])
        );
        assert!(lines.next_line().is_none());
        assert_eq!(lines.last_line, 6);
    }

    #[test]
    fn a_leading_byte_order_mark_is_skipped() {
        let mut lines = DataLines::new(Path::new("t.obj"), "\u{feff}v 0 0 0\n");
        assert_eq!(lines.next_line().unwrap().fields, vec!["v", "0", "0", "0"]);
    }

    #[test]
    fn long_quotes_are_cut_with_their_length() {
        let limit = "é".repeat(QUOTE_LIMIT);
        assert_eq!(quoted(&limit).to_string(), format!("`{limit}`"));
        let long = format!("{limit}xyz");
        assert_eq!(
            quoted(&long).to_string(),
            format!("`{limit}…` ({} characters)", QUOTE_LIMIT + 3)
        );
    }
}
