//! Draws a [`LiveState`] into a ratatui frame: the map on the left (UAV tracks, their current positions
//! `U0`, `U1`, …, the true emitter `T`, the estimate `E` with its 95 % ellipse, the standoff circle of
//! radius L_min circle), on the right the error series (RMSE, PCRLB, CRLB at the truth, m,
//! per step), the processes and the last hop latencies.

use ratatui::Frame;
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Style};
use ratatui::symbols::Marker;
use ratatui::text::Line;
use ratatui::widgets::canvas::{Canvas, Circle, Points};
use ratatui::widgets::{Axis, Block, Chart, Dataset, GraphType, Paragraph, Wrap};

use super::state::LiveState;

/// χ²₂(0.95) = −2 ln 0.05: the 95 % ellipse of a 2-D Gaussian is xᵀ M⁻¹ x = this.
const K95: f64 = 5.991_464_547_107_979;

const COLORS: [Color; 8] =
    [Color::Cyan, Color::Green, Color::Yellow, Color::Magenta, Color::Blue, Color::LightRed, Color::White, Color::Gray];

/// The points of the 95 % ellipse of `cov` around `center` (metres).
pub fn ellipse_95(center: [f64; 2], cov: [[f64; 2]; 2], n: usize) -> Vec<(f64, f64)> {
    let (a, b, c) = (cov[0][0], 0.5 * (cov[0][1] + cov[1][0]), cov[1][1]);
    let mean = 0.5 * (a + c);
    let d = (0.25 * (a - c) * (a - c) + b * b).sqrt();
    let (l1, l2) = ((mean + d).max(0.0), (mean - d).max(0.0));
    let theta = 0.5 * (2.0 * b).atan2(a - c);
    let (r1, r2) = ((K95 * l1).sqrt(), (K95 * l2).sqrt());
    (0..n)
        .map(|i| {
            let t = std::f64::consts::TAU * i as f64 / n as f64;
            let (x, y) = (r1 * t.cos(), r2 * t.sin());
            (center[0] + x * theta.cos() - y * theta.sin(), center[1] + x * theta.sin() + y * theta.cos())
        })
        .collect()
}

/// The map's bounds: every track point, the truth, the estimate with its ellipse and standoff circle,
/// with a margin, as a square in
/// metres (so circles look round on a terminal whose cells are twice as high as wide).
pub fn map_bounds(s: &LiveState, area: Rect) -> ([f64; 2], [f64; 2]) {
    let mut pts: Vec<[f64; 2]> = s.tracks.iter().flatten().copied().collect();
    pts.extend(s.truth);
    if let Some((p, cov)) = s.estimate {
        // The estimate, its ellipse and its standoff circle are part of the picture.
        pts.extend(ellipse_95(p, cov, 16).into_iter().map(|(x, y)| [x, y]));
        let r = s.standoff_m.max(0.0);
        pts.extend([[p[0] - r, p[1] - r], [p[0] + r, p[1] + r]]);
    }
    let pts: Vec<[f64; 2]> = pts.into_iter().filter(|p| p.iter().all(|v| v.is_finite())).collect();
    if pts.is_empty() {
        return ([0.0, 1.0], [0.0, 1.0]);
    }
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for p in &pts {
        (x0, x1, y0, y1) = (x0.min(p[0]), x1.max(p[0]), y0.min(p[1]), y1.max(p[1]));
    }
    // Cells are about twice as high as wide: width/height of the area in "metres per cell" terms.
    let aspect = (f64::from(area.width.max(1)) / (2.0 * f64::from(area.height.max(1)))).max(0.1);
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let half_h = (0.5 * (y1 - y0)).max(0.5 * (x1 - x0) / aspect).max(500.0) * 1.15;
    let half_w = half_h * aspect;
    ([cx - half_w, cx + half_w], [cy - half_h, cy + half_h])
}

/// The cell where the canvas in `area` (inside its border) puts a label at `p` (ratatui's rule).
pub fn label_cell(bounds: ([f64; 2], [f64; 2]), area: Rect, p: [f64; 2]) -> (u16, u16) {
    let inner = Block::bordered().inner(area);
    let (xb, yb) = bounds;
    let x = ((p[0] - xb[0]) * f64::from(inner.width - 1) / (xb[1] - xb[0])) as u16 + inner.left();
    let y = ((yb[1] - p[1]) * f64::from(inner.height - 1) / (yb[1] - yb[0])) as u16 + inner.top();
    (x, y)
}

/// The areas of the frame: map, series, processes.
pub fn areas(area: Rect) -> (Rect, Rect, Rect) {
    let [map, side] = Layout::horizontal([Constraint::Percentage(58), Constraint::Percentage(42)]).areas(area);
    let [series, procs] = Layout::vertical([Constraint::Percentage(55), Constraint::Percentage(45)]).areas(side);
    (map, series, procs)
}

/// Draws the whole view.
pub fn draw(frame: &mut Frame, s: &LiveState) {
    let (map, series, procs) = areas(frame.area());
    draw_map(frame, map, s);
    draw_series(frame, series, s);
    draw_processes(frame, procs, s);
}

fn draw_map(frame: &mut Frame, area: Rect, s: &LiveState) {
    let (xb, yb) = map_bounds(s, Block::bordered().inner(area));
    let title = format!(" {} — step {}/{} — q quits ", s.title, s.steps.saturating_sub(1), s.last_step);
    let canvas = Canvas::default()
        .block(Block::bordered().title(title))
        .marker(Marker::Braille)
        .x_bounds(xb)
        .y_bounds(yb)
        .paint(|ctx| {
            for (i, track) in s.tracks.iter().enumerate() {
                let coords: Vec<(f64, f64)> = track.iter().map(|p| (p[0], p[1])).collect();
                ctx.draw(&Points { coords: &coords, color: COLORS[i % COLORS.len()] });
            }
            if let Some((p, cov)) = s.estimate {
                ctx.draw(&Points { coords: &ellipse_95(p, cov, 120), color: Color::Red });
                if s.standoff_m > 0.0 {
                    ctx.draw(&Circle { x: p[0], y: p[1], radius: s.standoff_m, color: Color::DarkGray });
                }
            }
            ctx.layer();
            for (i, track) in s.tracks.iter().enumerate() {
                if let Some(p) = track.last() {
                    ctx.print(p[0], p[1], Line::styled(format!("U{i}"), Style::new().fg(COLORS[i % COLORS.len()])));
                }
            }
            if let Some(t) = s.truth {
                ctx.print(t[0], t[1], Line::styled("T", Style::new().fg(Color::LightGreen)));
            }
            if let Some((p, _)) = s.estimate {
                ctx.print(p[0], p[1], Line::styled("E", Style::new().fg(Color::Red)));
            }
        });
    frame.render_widget(canvas, area);
}

fn draw_series(frame: &mut Frame, area: Rect, s: &LiveState) {
    let all = s.rmse.iter().chain(&s.pcrlb).chain(&s.crlb);
    let ymax = all.clone().map(|p| p.1).fold(1.0, f64::max) * 1.1;
    let pcrlb_name = if s.truth.is_some() { "PCRLB" } else { "PCRLB at ẑ" };
    let datasets =
        [("RMSE", &s.rmse, Color::Yellow), (pcrlb_name, &s.pcrlb, Color::Cyan), ("CRLB", &s.crlb, Color::Green)]
            .into_iter()
            .filter(|(_, d, _)| !d.is_empty())
            .map(|(name, d, c)| {
                Dataset::default()
                    .name(name)
                    .marker(Marker::Braille)
                    .graph_type(GraphType::Line)
                    .style(Style::new().fg(c))
                    .data(d)
            })
            .collect::<Vec<_>>();
    let xmax = (s.last_step as f64).max(1.0);
    let chart = Chart::new(datasets)
        .block(Block::bordered().title(if s.truth.is_some() || !s.rmse.is_empty() {
            " error (m) per step "
        } else {
            " error (m): no truth (external front end) "
        }))
        .x_axis(Axis::default().bounds([0.0, xmax]).labels(["0".to_string(), format!("{}", s.last_step)]))
        .y_axis(Axis::default().bounds([0.0, ymax]).labels(["0".to_string(), format!("{ymax:.0}")]));
    frame.render_widget(chart, area);
}

fn draw_processes(frame: &mut Frame, area: Rect, s: &LiveState) {
    let mut lines: Vec<Line> = s
        .processes
        .iter()
        .map(|p| {
            Line::from(format!(
                "{:<12} pid {:<8} {:<8} restarts {}  rejected {}",
                p.role,
                p.pid,
                if p.running { "running" } else { "exited" },
                p.restarts,
                s.rejected_of(&p.role)
            ))
        })
        .collect();
    lines.push(Line::from(format!("planner in charge: {}", s.planner.as_deref().unwrap_or("-"))));
    let safety = Line::from(s.safety_line());
    lines.push(if s.certified == Some(false) { safety.style(Style::new().fg(Color::Red)) } else { safety });
    lines.push(Line::from(s.receiver.line()));
    lines.push(Line::from(format!(
        "rejected messages: {}",
        ["monitor", "estimator", "planner", "emitter-sim"].iter().map(|r| s.rejected_of(r)).sum::<u64>()
    )));
    let hops: Vec<String> =
        s.hops.iter().map(|(name, v)| format!("{name} {}", v.map_or("-".into(), |us| format!("{us:.0} µs")))).collect();
    if !hops.is_empty() {
        lines.push(Line::from(format!("last hops: {}", hops.join(", "))));
    }
    if let Some((p, cov)) = s.estimate {
        let e = ellipse_95(p, cov, 4);
        let axis = |q: (f64, f64)| (q.0 - p[0]).hypot(q.1 - p[1]);
        let place = s
            .frame
            .and_then(|f| f.to_geodetic(p).ok())
            .map_or(String::new(), |q| format!(" = {:.6}°, {:.6}°", q.lat_deg, q.lon_deg));
        lines.push(Line::from(format!(
            "estimate ({:.0}, {:.0}) m{place}, 95 % ellipse {:.0} × {:.0} m",
            p[0],
            p[1],
            2.0 * axis(e[0]),
            2.0 * axis(e[1])
        )));
    }
    if !s.links.is_empty() {
        let links: Vec<String> = s
            .links
            .iter()
            .enumerate()
            .map(|(i, l)| if l == "quiet" { format!("U{i} QUIET") } else { format!("U{i} {l}") })
            .collect();
        lines.push(Line::from(format!("links: {}", links.join(", "))));
    }
    lines.push(Line::from("map: U0… UAVs, T true emitter, E estimate; red the 95 % ellipse, grey the L_min circle"));
    if !s.note.is_empty() {
        lines.push(Line::from(s.note.clone()));
    }
    let text = Paragraph::new(lines).wrap(Wrap { trim: true }).block(Block::bordered().title(" processes "));
    frame.render_widget(text, area);
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratatui::Terminal;
    use ratatui::backend::TestBackend;

    fn state() -> LiveState {
        let mut s = LiveState::new("launch t", 24, 3000.0);
        s.tracks = vec![
            vec![[1500.0, 500.0], [2000.0, 700.0]],
            vec![[10000.0, 1500.0], [10400.0, 1800.0]],
            vec![[5000.0, 8500.0], [5400.0, 8800.0]],
        ];
        s.truth = Some([25000.0, 15000.0]);
        // An ellipse long in x: 95 % semi-axes sqrt(5.99 · 4e6) ≈ 4895 m and sqrt(5.99 · 1e5) ≈ 774 m.
        s.estimate = Some(([24000.0, 14000.0], [[4.0e6, 0.0], [0.0, 1.0e5]]));
        s
    }

    fn render(s: &LiveState) -> (ratatui::buffer::Buffer, Rect) {
        let mut t = Terminal::new(TestBackend::new(160, 48)).unwrap();
        t.draw(|f| draw(f, s)).unwrap();
        let buffer = t.backend().buffer().clone();
        let (map, _, _) = areas(buffer.area);
        (buffer, map)
    }

    /// The whole screen of `s`, line by line.
    fn whole(s: &LiveState) -> String {
        let (b, _) = render(s);
        (0..b.area.height).map(|y| text_at(&b, (0, y), b.area.width)).collect::<Vec<_>>().join("\n")
    }

    fn text_at(b: &ratatui::buffer::Buffer, (x, y): (u16, u16), len: u16) -> String {
        (x..x + len).map(|x| b[(x, y)].symbol().to_string()).collect()
    }

    /// With aircraft the autopilot links are listed, a quiet one in capitals, and its going quiet is the
    /// note.
    #[test]
    fn the_links_of_the_aircraft_are_shown() {
        let mut s = state();
        assert!(!whole(&s).contains("links:"));
        for (uav, state) in [(0, "flying"), (1, "flying"), (2, "flying"), (1, "quiet")] {
            s.apply_event(&serde_json::json!({"event": "link", "uav": uav, "state": state, "step": 18}));
        }
        let text = whole(&s);
        assert!(text.contains("links: U0 flying, U1 QUIET, U2 flying"), "{text}");
        assert!(s.note.contains("UAV 1: link quiet (step 18)"), "{}", s.note);
    }

    /// With an origin the estimate's line also gives it as latitude/longitude; without, it does not.
    #[test]
    fn a_run_with_an_origin_shows_the_estimate_as_latitude_longitude() {
        let mut s = state();
        assert!(!whole(&s).contains('°'));
        let sc = model::Scenario::from_toml_str(include_str!("../../scenarios/geo.toml")).unwrap();
        s.frame = sc.frame();
        let at = sc.frame().unwrap().to_geodetic([24000.0, 14000.0]).unwrap();
        let text = whole(&s);
        assert!(text.contains(&format!("= {:.6}°, {:.6}°", at.lat_deg, at.lon_deg)), "{text}");
    }

    #[test]
    fn the_map_shows_the_uavs_truth_and_estimate_where_they_are() {
        let s = state();
        let (b, map) = render(&s);
        let bounds = map_bounds(&s, Block::bordered().inner(map));
        for (i, track) in s.tracks.iter().enumerate() {
            let cell = label_cell(bounds, map, *track.last().unwrap());
            assert_eq!(text_at(&b, cell, 2), format!("U{i}"), "UAV {i} at {cell:?}");
        }
        assert_eq!(text_at(&b, label_cell(bounds, map, [25000.0, 15000.0]), 1), "T");
        assert_eq!(text_at(&b, label_cell(bounds, map, [24000.0, 14000.0]), 1), "E");
        // UAV 1 is right of UAV 0, UAV 2 above it.
        let c0 = label_cell(bounds, map, s.tracks[0][1]);
        assert!(label_cell(bounds, map, s.tracks[1][1]).0 > c0.0 && label_cell(bounds, map, s.tracks[2][1]).1 < c0.1);
    }

    #[test]
    fn the_ellipse_is_drawn_around_the_estimate_with_its_95_percent_axes() {
        let s = state();
        let (b, map) = render(&s);
        let bounds = map_bounds(&s, Block::bordered().inner(map));
        let braille = |cell: (u16, u16)| {
            // A dot of the ellipse in this cell or a neighbour (cell rounding).
            [(0, 0), (1, 0), (-1, 0), (0, 1), (0, -1)].iter().any(|(dx, dy)| {
                let c = ((cell.0 as i32 + dx) as u16, (cell.1 as i32 + dy) as u16);
                b[c].symbol().chars().next().is_some_and(|ch| ('\u{2801}'..='\u{28ff}').contains(&ch))
            })
        };
        let semi_major = (K95 * 4.0e6).sqrt();
        let semi_minor = (K95 * 1.0e5).sqrt();
        for p in [[24000.0 + semi_major, 14000.0], [24000.0 - semi_major, 14000.0], [24000.0, 14000.0 + semi_minor]] {
            assert!(braille(label_cell(bounds, map, p)), "no ellipse dot at {p:?}");
        }
        // Drawn in the estimate's colour.
        let end = label_cell(bounds, map, [24000.0 + semi_major, 14000.0]);
        assert!([-1i32, 0, 1].iter().any(|dx| b[((end.0 as i32 + dx) as u16, end.1)].fg == Color::Red));
        let text: String = (0..b.area.height).map(|y| text_at(&b, (0, y), b.area.width)).collect();
        assert!(text.contains("95 % ellipse 9791 × 1548 m"), "{text}");
    }

    #[test]
    fn ellipse_points_lie_on_the_95_percent_contour() {
        let cov = [[3.0e4, 1.2e4], [1.2e4, 2.0e4]];
        let det = cov[0][0] * cov[1][1] - cov[0][1] * cov[1][0];
        for (x, y) in ellipse_95([10.0, -5.0], cov, 16) {
            let (dx, dy) = (x - 10.0, y + 5.0);
            let q = (cov[1][1] * dx * dx - 2.0 * cov[0][1] * dx * dy + cov[0][0] * dy * dy) / det;
            assert!((q - K95).abs() < 1e-9 * K95, "{q}");
        }
    }
}
