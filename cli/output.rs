//! How a subcommand's result is shown: JSON (`--json`) or an aligned key/value table, plus the
//! warnings and failures that go to stderr.

use std::fmt::Write as _;

use serde::Serialize;

/// A message for stderr that accompanies a printed result.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Diagnostic {
    /// `warning: …`; the exit code stays 0.
    Warning(String),
    /// `error: …`; the result is still printed but the exit code is 1.
    Failure(String),
}

/// A subcommand result that can be printed either way.
pub trait Report: Serialize {
    /// The human-readable form.
    fn table(&self) -> Table;

    /// The whole human-readable output (the rendered [`Report::table`] unless a report lays itself out).
    fn text(&self) -> String {
        self.table().render()
    }

    /// Warnings or failures to print on stderr after the result.
    fn diagnostics(&self) -> Vec<Diagnostic> {
        Vec::new()
    }
}

/// Aligned `label   value unit` lines.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Table {
    rows: Vec<(String, String)>,
}

impl Table {
    /// An empty table.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a row; `value` already carries its unit.
    /// Adds a row only when there is a value.
    pub fn row_opt(self, label: impl Into<String>, value: Option<String>) -> Self {
        match value {
            Some(v) => self.row(label, v),
            None => self,
        }
    }

    pub fn row(mut self, label: impl Into<String>, value: impl Into<String>) -> Self {
        self.rows.push((label.into(), value.into()));
        self
    }

    /// The table as text, one row per line, values aligned in one column.
    pub fn render(&self) -> String {
        let width = self.rows.iter().map(|(l, _)| l.chars().count()).max().unwrap_or(0).max(14) + 2;
        let mut out = String::new();
        for (label, value) in &self.rows {
            let pad = width - label.chars().count();
            let _ = writeln!(out, "{label}{:pad$}{value}", "");
        }
        out
    }
}

/// A number with about six significant digits: plain notation between 1e-3 and 1e7, scientific outside.
pub fn num(v: f64) -> String {
    if !v.is_finite() {
        return if v.is_nan() {
            "NaN".into()
        } else if v > 0.0 {
            "inf".into()
        } else {
            "-inf".into()
        };
    }
    if v == 0.0 {
        return "0".into();
    }
    let mag = v.abs();
    if !(1e-3..1e7).contains(&mag) {
        return format!("{v:.5e}");
    }
    let decimals = (5 - mag.log10().floor() as i32).max(0) as usize;
    format!("{v:.decimals$}")
}

/// `(x, y)` with [`num`] formatting.
pub fn pair(p: [f64; 2]) -> String {
    format!("({}, {})", num(p[0]), num(p[1]))
}

/// `[[a, b], [c, d]]` with [`num`] formatting.
pub fn matrix(m: [[f64; 2]; 2]) -> String {
    format!("[[{}, {}], [{}, {}]]", num(m[0][0]), num(m[0][1]), num(m[1][0]), num(m[1][1]))
}

/// A nalgebra 2×2 matrix as nested rows, the JSON form of every matrix.
pub use tdoa::matrix_to_rows as rows;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers() {
        assert_eq!(num(1655.5812), "1655.58");
        assert_eq!(num(57.543), "57.5430");
        assert_eq!(num(2_741_960.4), "2741960");
        assert_eq!(num(3.0e-7), "3.00000e-7");
        assert_eq!(num(0.0), "0");
        assert_eq!(num(-12.5), "-12.5000");
        assert_eq!(num(f64::INFINITY), "inf");
    }

    #[test]
    fn alignment() {
        let t = Table::new().row("CRLB", "1655.58 m").row("condition number", "3.2").render();
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines[0].find('1'), lines[1].find('3'));
    }
}
