//! A table of text cells in the paper's layout, rendered three ways: aligned text for the terminal,
//! Markdown for EXPERIMENTS.md, CSV for analysis. [`Grid::compare`] adds a method's three rows: our
//! numbers, the paper's numbers and the difference.

use std::fmt::Write as _;

/// A titled table of text cells.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Grid {
    /// File-name slug (`table2`, `table6-terminal`), unique within an experiment.
    pub name: String,
    /// Title line.
    pub title: String,
    /// Column headers (the first columns are labels).
    pub header: Vec<String>,
    /// Rows of cells, as long as the header.
    pub rows: Vec<Vec<String>>,
}

/// A number with `decimals` decimals; "—" for a missing or non-finite value.
pub fn cell(v: Option<f64>, decimals: usize) -> String {
    match v {
        Some(x) if x.is_finite() => format!("{x:.decimals$}"),
        Some(x) if x.is_nan() => "—".to_string(),
        Some(x) => format!("{x}"),
        None => "—".to_string(),
    }
}

/// A number with 4 significant digits: plain between 1e-3 and 1e6, scientific outside (for times in
/// seconds that span microseconds to seconds); "—" for a missing or non-finite value.
pub fn sig(v: f64) -> String {
    if !v.is_finite() {
        return cell(Some(v), 0);
    }
    if v == 0.0 {
        return "0".to_string();
    }
    let mag = v.abs();
    if (1e-3..1e6).contains(&mag) {
        let decimals = (3 - mag.log10().floor() as i32).max(0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{v:.3e}")
    }
}

/// `ours − paper` with its relative size, e.g. `+12.30 (+5.1 %)`; "—" when either is missing.
pub fn delta_cell(ours: f64, paper: Option<f64>, decimals: usize) -> String {
    match paper {
        Some(p) if ours.is_finite() && p.is_finite() => {
            let d = ours - p;
            if p != 0.0 {
                format!("{d:+.decimals$} ({:+.1} %)", d / p.abs() * 100.0)
            } else {
                format!("{d:+.decimals$}")
            }
        }
        _ => "—".to_string(),
    }
}

impl Grid {
    /// An empty grid with these headers.
    pub fn new(name: &str, title: &str, header: &[&str]) -> Self {
        Self {
            name: name.to_string(),
            title: title.to_string(),
            header: header.iter().map(|h| h.to_string()).collect(),
            rows: Vec::new(),
        }
    }

    /// Appends a row (padded or cut to the header's width).
    pub fn push(&mut self, mut row: Vec<String>) {
        row.resize(self.header.len(), String::new());
        self.rows.push(row);
    }

    /// Appends the three rows of one method: `label | ours | …`, `label | paper | …` and
    /// `label | Δ | …` (ours − paper). The grid's header must be `[label, source, columns…]`.
    pub fn compare(&mut self, label: &str, ours: &[f64], paper: Option<&[f64]>, decimals: usize) {
        self.compare_with(label, ours, paper, |v| cell(Some(v), decimals), |o, p| delta_cell(o, Some(p), decimals));
    }

    /// [`Grid::compare`] with 4 significant digits ([`sig`]) instead of fixed decimals; the Δ row gives
    /// the ratio ours/paper (for times that differ by orders of magnitude).
    pub fn compare_sig(&mut self, label: &str, ours: &[f64], paper: Option<&[f64]>) {
        self.compare_with(label, ours, paper, sig, |o, p| {
            if o.is_finite() && p.is_finite() && p != 0.0 { format!("×{}", sig(o / p)) } else { "—".to_string() }
        });
    }

    fn compare_with(
        &mut self,
        label: &str,
        ours: &[f64],
        paper: Option<&[f64]>,
        fmt: impl Fn(f64) -> String,
        delta: impl Fn(f64, f64) -> String,
    ) {
        let mut row = vec![label.to_string(), "ours".to_string()];
        row.extend(ours.iter().map(|v| fmt(*v)));
        self.push(row);
        if let Some(p) = paper {
            let mut row = vec![String::new(), "paper".to_string()];
            row.extend(p.iter().map(|v| fmt(*v)));
            self.push(row);
            let mut row = vec![String::new(), "Δ".to_string()];
            row.extend(ours.iter().zip(p).map(|(o, p)| delta(*o, *p)));
            self.push(row);
        }
    }

    fn widths(&self) -> Vec<usize> {
        let mut w: Vec<usize> = self.header.iter().map(|h| h.chars().count()).collect();
        for r in &self.rows {
            for (i, c) in r.iter().enumerate() {
                w[i] = w[i].max(c.chars().count());
            }
        }
        w
    }

    /// Aligned text: title, header, a rule, the rows (labels left, numbers right).
    pub fn text(&self) -> String {
        let w = self.widths();
        let line = |cells: &[String]| {
            let mut s = String::new();
            for (i, c) in cells.iter().enumerate() {
                let pad = w[i] - c.chars().count();
                if i < 2 {
                    let _ = write!(s, "{c}{:pad$}  ", "");
                } else {
                    let _ = write!(s, "{:pad$}{c}  ", "");
                }
            }
            s.trim_end().to_string()
        };
        let mut out = format!("{}\n{}\n", self.title, line(&self.header));
        let _ = writeln!(out, "{}", "-".repeat(w.iter().map(|x| x + 2).sum::<usize>().saturating_sub(2)));
        for r in &self.rows {
            let _ = writeln!(out, "{}", line(r));
        }
        out
    }

    /// A Markdown table under a `###` title.
    pub fn markdown(&self) -> String {
        let esc = |c: &str| c.replace('|', "\\|");
        let mut out = format!(
            "### {}\n\n| {} |\n|",
            self.title,
            self.header.iter().map(|h| esc(h)).collect::<Vec<_>>().join(" | ")
        );
        for i in 0..self.header.len() {
            out.push_str(if i < 2 { "---|" } else { "---:|" });
        }
        out.push('\n');
        for r in &self.rows {
            let _ = writeln!(out, "| {} |", r.iter().map(|c| esc(c)).collect::<Vec<_>>().join(" | "));
        }
        out
    }

    /// RFC 4180 CSV: the header line, then the rows (fields with commas, quotes or newlines quoted).
    pub fn csv(&self) -> String {
        let field = |c: &str| {
            if c.contains([',', '"', '\n']) { format!("\"{}\"", c.replace('"', "\"\"")) } else { c.to_string() }
        };
        let mut out = String::new();
        for r in std::iter::once(&self.header).chain(&self.rows) {
            let _ = writeln!(out, "{}", r.iter().map(|c| field(c)).collect::<Vec<_>>().join(","));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Grid {
        let mut g = Grid::new("t", "Table X", &["Method", "source", "Final CRLB (m)", "CI95"]);
        g.compare("single", &[250.0, 1.5], Some(&[241.62, 1.43]), 2);
        g.compare("formation", &[330.0, 2.0], None, 2);
        g
    }

    #[test]
    fn compare_adds_ours_paper_and_delta() {
        let g = sample();
        assert_eq!(g.rows.len(), 4);
        assert_eq!(g.rows[0], ["single", "ours", "250.00", "1.50"]);
        assert_eq!(g.rows[1], ["", "paper", "241.62", "1.43"]);
        assert_eq!(g.rows[2][2], "+8.38 (+3.5 %)");
        assert_eq!(g.rows[3][0], "formation");
    }

    #[test]
    fn renderings() {
        let g = sample();
        let text = g.text();
        let lines: Vec<&str> = text.lines().collect();
        // Numbers are right-aligned: every data line ends at the same column.
        let ends: Vec<usize> = lines[3..].iter().map(|l| l.chars().count()).collect();
        assert!(ends.windows(2).all(|w| w[0] == w[1]), "{text}");
        let md = g.markdown();
        assert!(md.contains("| Method | source | Final CRLB (m) | CI95 |") && md.contains("|---|---|---:|---:|"));
        let csv = g.csv();
        assert_eq!(csv.lines().count(), 5);
        assert!(csv.contains("\"+8.38 (+3.5 %)\"") || csv.contains("+8.38 (+3.5 %)"));
        let mut q = Grid::new("q", "Q", &["a", "b"]);
        q.push(vec!["x,y".into(), "say \"hi\"".into()]);
        assert_eq!(q.csv().lines().nth(1).unwrap(), "\"x,y\",\"say \"\"hi\"\"\"");
    }

    #[test]
    fn significant_digits_and_ratios() {
        assert_eq!(sig(0.000_123_456), "1.235e-4");
        assert_eq!(sig(0.152_02), "0.1520");
        assert_eq!(sig(345.83), "345.8");
        assert_eq!(sig(2.5e7), "2.500e7");
        let mut g = Grid::new("t", "T", &["m", "s", "time"]);
        g.compare_sig("mc", &[0.0027], Some(&[1.18]));
        assert_eq!(g.rows[2][2], "×0.002288");
    }

    #[test]
    fn missing_values() {
        assert_eq!(cell(None, 2), "—");
        assert_eq!(cell(Some(f64::NAN), 2), "—");
        assert_eq!(cell(Some(f64::INFINITY), 2), "inf");
        assert_eq!(delta_cell(f64::NAN, Some(1.0), 2), "—");
    }
}
