//! Small PNG line charts for evaluation figures (error versus coefficient count, Green 2005
//! Fig. 3-3): linear x axis, linear or log-10 y axis, ticks and labels in the 5 x 7 font of
//! [`crate::text`], a legend in a row under the axis, one colour per series, several charts
//! side by side as panels.
//!
//! Conventions: pixel `(0, 0)` is the top-left corner, rows go down; colours are 8-bit sRGB.
//! Points whose y is not positive are left out on a log axis (and break the line there).
//! Series colours come from [`PALETTE`] in series order (Okabe & Ito 2008, "Color universal
//! design", chosen to stay distinct for colour-blind readers).

use crate::text;
use relight_scene::error::SceneError;
use std::path::Path;

/// Series colours, in order (Okabe-Ito palette without its yellow, which is unreadable on
/// white).
pub const PALETTE: [[u8; 3]; 7] = [
    [0, 114, 178],   // blue
    [213, 94, 0],    // vermillion
    [0, 158, 115],   // bluish green
    [204, 121, 167], // reddish purple
    [86, 180, 233],  // sky blue
    [230, 159, 0],   // orange
    [0, 0, 0],       // black
];

const WHITE: [u8; 3] = [255, 255, 255];
const INK: [u8; 3] = [30, 30, 30];
const GRID: [u8; 3] = [225, 225, 225];
/// Font scale of every label (5 x 7 glyphs drawn 2 pixels per font pixel: 12 x 14 cells).
const SCALE: usize = 2;
const CHAR_H: usize = 7 * SCALE;

/// One line of a chart.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend label.
    pub name: String,
    /// `(x, y)` points, drawn in the given order.
    pub points: Vec<(f64, f64)>,
    /// Draw a small square at every point (for sparse series).
    pub markers: bool,
}

/// How the y axis maps values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum YScale {
    /// Linear, tick labels as numbers.
    Linear,
    /// Base-10 logarithmic over whole decades, tick labels as numbers.
    Log,
    /// Base-10 logarithmic, values are fractions and tick labels are percentages
    /// (`0.01` -> `1%`).
    LogPercent,
}

/// A line chart: title, axis labels, series.
#[derive(Clone, Debug)]
pub struct Chart {
    /// Title above the plot area.
    pub title: String,
    /// Label under the x axis.
    pub x_label: String,
    /// Label left of the y axis (drawn vertically).
    pub y_label: String,
    /// Y axis mapping.
    pub y_scale: YScale,
    /// The lines; series `i` is drawn in `PALETTE[i % PALETTE.len()]`.
    pub series: Vec<Series>,
}

/// An 8-bit RGB raster to draw on (row-major, white when created).
#[derive(Clone, Debug)]
pub struct Canvas {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width * height` pixels, row-major from the top.
    pub pixels: Vec<[u8; 3]>,
}

impl Canvas {
    /// A white canvas.
    pub fn new(width: usize, height: usize) -> Canvas {
        Canvas {
            width,
            height,
            pixels: vec![WHITE; width * height],
        }
    }

    /// Sets pixel `(x, y)` if it is inside the canvas.
    #[inline]
    pub fn put(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height {
            self.pixels[y as usize * self.width + x as usize] = c;
        }
    }

    /// Fills the rectangle `[x0, x1) x [y0, y1)` (clipped).
    pub fn fill_rect(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, c: [u8; 3]) {
        for y in y0..y1 {
            for x in x0..x1 {
                self.put(x, y, c);
            }
        }
    }

    /// A line of `thickness` pixels from `(x0, y0)` to `(x1, y1)` (a square brush stamped at
    /// every step of the longer axis: a DDA).
    pub fn line(&mut self, p0: (f64, f64), p1: (f64, f64), c: [u8; 3], thickness: usize) {
        let (dx, dy) = (p1.0 - p0.0, p1.1 - p0.1);
        let steps = dx.abs().max(dy.abs()).ceil().max(1.0) as usize;
        let (lo, hi) = (-((thickness as i64 - 1) / 2), thickness as i64 / 2);
        for s in 0..=steps {
            let t = s as f64 / steps as f64;
            let (x, y) = (
                (p0.0 + t * dx).round() as i64,
                (p0.1 + t * dy).round() as i64,
            );
            self.fill_rect(x + lo, y + lo, x + hi + 1, y + hi + 1, c);
        }
    }

    /// `label` in colour `c` with its top-left corner at `(x, y)`; `vertical` rotates it a
    /// quarter turn counter-clockwise (reading bottom to top, top-left of the rotated box at
    /// `(x, y)`).
    pub fn text(&mut self, x: i64, y: i64, label: &str, c: [u8; 3], vertical: bool) {
        // Draw through text::draw_label on a black scratch image: its glyph pixels are white.
        let (w, h) = (text::text_width(label, SCALE) + 4, CHAR_H + 4);
        let mut scratch = vec![[0u8; 3]; w * h];
        text::draw_label(&mut scratch, w, 0, 0, SCALE, label);
        for sy in 2..h - 2 {
            for sx in 2..w - 2 {
                if scratch[sy * w + sx] != WHITE {
                    continue;
                }
                let (u, v) = ((sx - 2) as i64, (sy - 2) as i64);
                if vertical {
                    let tw = (w - 4) as i64;
                    self.put(x + v, y + tw - 1 - u, c);
                } else {
                    self.put(x + u, y + v, c);
                }
            }
        }
    }

    /// Draws `chart` into the rectangle `(x0, y0, w, h)` of the canvas.
    pub fn draw_chart(&mut self, chart: &Chart, x0: usize, y0: usize, w: usize, h: usize) {
        draw_chart(self, chart, x0 as i64, y0 as i64, w as i64, h as i64);
    }
}

/// A "nice" tick step (1, 2 or 5 times a power of ten) giving at most about `max_ticks` ticks
/// over `range`.
fn nice_step(range: f64, max_ticks: usize) -> f64 {
    let raw = (range / max_ticks as f64).max(f64::MIN_POSITIVE);
    let p = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * p)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * p)
}

/// A number with at most 4 significant digits and no trailing zeros.
fn format_number(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let digits = (3 - v.abs().log10().floor() as i32).clamp(0, 8) as usize;
    let s = format!("{v:.digits$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// Label of the decade `10^k` on a log axis.
fn decade_label(k: i32, scale: YScale) -> String {
    match scale {
        YScale::LogPercent => format!("{}%", format_number(10f64.powi(k + 2))),
        _ => format_number(10f64.powi(k)),
    }
}

fn draw_chart(cv: &mut Canvas, chart: &Chart, x0: i64, y0: i64, w: i64, h: i64) {
    let log = chart.y_scale != YScale::Linear;
    let usable = |p: &(f64, f64)| p.0.is_finite() && p.1.is_finite() && (!log || p.1 > 0.0);
    let pts = || {
        chart
            .series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|p| usable(p))
    };
    // Data ranges: x from 0 (or its minimum) to a whole tick; y over whole decades on log.
    let (mut xmin, mut xmax) =
        pts().fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.0), a.1.max(p.0)));
    let (mut ymin, mut ymax) =
        pts().fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.1), a.1.max(p.1)));
    if xmin > xmax {
        (xmin, xmax, ymin, ymax) = (0.0, 1.0, 0.1, 1.0);
    }
    xmin = xmin.min(0.0);
    let xstep = nice_step(xmax - xmin, 8);
    xmax = (xmax / xstep).ceil() * xstep;
    let (ylo, yhi) = if log {
        let lo = ymin.log10().floor();
        let hi = ymax.log10().ceil().max(lo + 1.0);
        (lo, hi)
    } else {
        let lo = ymin.min(0.0);
        let step = nice_step((ymax - lo).max(1e-12), 6);
        (lo, (ymax / step).ceil() * step)
    };
    // Plot area inside the panel: room for the title, tick labels and axis labels.
    let (left, right, top, bottom) = (x0 + 26 + 7 * 12, x0 + w - 26, y0 + 34, y0 + h - 78);
    let (pw, ph) = ((right - left) as f64, (bottom - top) as f64);
    let sx = |x: f64| left as f64 + (x - xmin) / (xmax - xmin) * pw;
    let sy = |y: f64| {
        let t = if log {
            (y.log10() - ylo) / (yhi - ylo)
        } else {
            (y - ylo) / (yhi - ylo)
        };
        bottom as f64 - t * ph
    };
    // Grid and y ticks.
    let ytick = |cv: &mut Canvas, y: f64, label: Option<String>, major: bool| {
        let py = sy(y).round() as i64;
        if major {
            cv.fill_rect(left, py, right, py + 1, GRID);
        }
        cv.fill_rect(left - if major { 6 } else { 3 }, py, left, py + 1, INK);
        if let Some(l) = label {
            let tw = text::text_width(&l, SCALE) as i64;
            cv.text(left - 9 - tw, py - CHAR_H as i64 / 2, &l, INK, false);
        }
    };
    if log {
        for k in ylo as i32..=yhi as i32 {
            ytick(
                cv,
                10f64.powi(k),
                Some(decade_label(k, chart.y_scale)),
                true,
            );
            if k < yhi as i32 {
                for m in 2..10 {
                    ytick(cv, m as f64 * 10f64.powi(k), None, false);
                }
            }
        }
    } else {
        let step = nice_step(yhi - ylo, 6);
        let mut y = ylo;
        while y <= yhi + 1e-9 * step {
            ytick(cv, y, Some(format_number(y)), true);
            y += step;
        }
    }
    // X ticks.
    let mut x = xmin;
    while x <= xmax + 1e-9 * xstep {
        let px = sx(x).round() as i64;
        cv.fill_rect(px, top, px + 1, bottom, GRID);
        cv.fill_rect(px, bottom, px + 1, bottom + 6, INK);
        let l = format_number(x);
        let tw = text::text_width(&l, SCALE) as i64;
        cv.text(px - tw / 2, bottom + 10, &l, INK, false);
        x += xstep;
    }
    // Axes, title, axis labels.
    cv.fill_rect(left, top, left + 1, bottom + 1, INK);
    cv.fill_rect(left, bottom, right + 1, bottom + 1, INK);
    let centre = |l: &str, a: i64, b: i64| (a + b) / 2 - text::text_width(l, SCALE) as i64 / 2;
    cv.text(
        centre(&chart.title, x0, x0 + w),
        y0 + 10,
        &chart.title,
        INK,
        false,
    );
    cv.text(
        centre(&chart.x_label, left, right),
        bottom + 32,
        &chart.x_label,
        INK,
        false,
    );
    let yl = text::text_width(&chart.y_label, SCALE) as i64;
    cv.text(
        x0 + 6,
        (top + bottom) / 2 - yl / 2,
        &chart.y_label,
        INK,
        true,
    );
    // Series: lines (broken at unusable points), then markers.
    for (i, s) in chart.series.iter().enumerate() {
        let c = PALETTE[i % PALETTE.len()];
        let mut prev: Option<(f64, f64)> = None;
        for p in &s.points {
            if !usable(p) {
                prev = None;
                continue;
            }
            let q = (sx(p.0), sy(p.1));
            if let Some(a) = prev {
                cv.line(a, q, c, 2);
            }
            if s.markers {
                let (mx, my) = (q.0.round() as i64, q.1.round() as i64);
                cv.fill_rect(mx - 3, my - 3, mx + 4, my + 4, c);
            }
            prev = Some(q);
        }
    }
    // Legend: one row under the x-axis label, entries side by side (never over the data).
    let entry_w = |s: &Series| 36 + (text::text_width(&s.name, SCALE) as i64) + 16;
    let total: i64 = chart.series.iter().map(entry_w).sum();
    let mut lx = ((left + right) / 2 - total / 2).max(x0 + 4);
    let ly = y0 + h - 6 - CHAR_H as i64;
    for (i, s) in chart.series.iter().enumerate() {
        let c = PALETTE[i % PALETTE.len()];
        let mid = (ly + CHAR_H as i64 / 2) as f64;
        cv.line((lx as f64 + 4.0, mid), (lx as f64 + 28.0, mid), c, 3);
        if s.markers {
            cv.fill_rect(lx + 13, mid as i64 - 3, lx + 20, mid as i64 + 4, c);
        }
        cv.text(lx + 36, ly, &s.name, c, false);
        lx += entry_w(s);
    }
}

/// Renders `charts` as panels of `panel_w x panel_h` pixels side by side.
pub fn render_panels(charts: &[Chart], panel_w: usize, panel_h: usize) -> Canvas {
    let mut cv = Canvas::new(panel_w * charts.len().max(1), panel_h);
    for (i, c) in charts.iter().enumerate() {
        cv.draw_chart(c, i * panel_w, 0, panel_w, panel_h);
    }
    cv
}

/// Writes `charts` as panels side by side to a PNG at `path` (atomically, through
/// [`relight_scene::io::write_png_srgb8`]).
///
/// # Errors
/// Any IO error, naming the file.
pub fn write_png(
    path: &Path,
    charts: &[Chart],
    panel_w: usize,
    panel_h: usize,
) -> Result<(), SceneError> {
    let cv = render_panels(charts, panel_w, panel_h);
    relight_scene::io::write_png_srgb8(path, cv.width, cv.height, &cv.pixels)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chart() -> Chart {
        Chart {
            title: "(A) GLOSSY".into(),
            x_label: "COEFFICIENTS".into(),
            y_label: "RELATIVE L2 ERROR".into(),
            y_scale: YScale::LogPercent,
            series: vec![
                Series {
                    name: "SG".into(),
                    points: vec![(7.0, 0.2), (14.0, 0.05), (21.0, 0.01)],
                    markers: true,
                },
                Series {
                    name: "SH".into(),
                    points: (1..=10).map(|n| ((n * n) as f64, 1.0 / n as f64)).collect(),
                    markers: false,
                },
            ],
        }
    }

    #[test]
    fn ticks_and_labels() {
        assert_eq!(nice_step(100.0, 8), 20.0);
        assert_eq!(nice_step(7.0, 8), 1.0);
        assert_eq!(format_number(0.001), "0.001");
        assert_eq!(format_number(40.0), "40");
        assert_eq!(decade_label(-2, YScale::LogPercent), "1%");
        assert_eq!(decade_label(-4, YScale::LogPercent), "0.01%");
        assert_eq!(decade_label(0, YScale::LogPercent), "100%");
        assert_eq!(decade_label(-1, YScale::Log), "0.1");
    }

    #[test]
    fn draws_every_series_colour_and_writes_a_png() {
        let cv = render_panels(&[chart(), chart()], 400, 300);
        assert_eq!((cv.width, cv.height), (800, 300));
        for c in &PALETTE[..2] {
            // Both halves hold each series colour (lines, markers, legend).
            for half in 0..2 {
                let n = (0..300)
                    .flat_map(|y| (half * 400..half * 400 + 400).map(move |x| (x, y)))
                    .filter(|&(x, y)| cv.pixels[y * 800 + x] == *c)
                    .count();
                assert!(n > 100, "colour {c:?} in panel {half}: {n} pixels");
            }
        }
        assert!(cv.pixels.contains(&INK));
        let dir = std::env::temp_dir().join(format!("relight-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("chart.png");
        write_png(&path, &[chart()], 400, 300).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn log_axis_skips_non_positive_points() {
        let mut c = chart();
        c.series[0].points.push((28.0, 0.0));
        c.series[0].points.push((35.0, f64::NAN));
        let cv = render_panels(&[c], 400, 300);
        assert_eq!(cv.pixels.len(), 400 * 300);
    }
}
