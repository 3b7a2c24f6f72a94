//! The demo report: an `index.html` with one section per capability, tables and inline SVG
//! plots drawn with plotters' SVG backend.
//!
//! Entry points: [`Report`] (collect sections, write atomically), [`xy_plot`], [`histogram`],
//! [`heatmap`], [`table`].

use anyhow::Result;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

pub struct Section {
    pub id: String,
    pub title: String,
    pub html: String,
}

/// A report under construction.
pub struct Report {
    pub dir: PathBuf,
    sections: Vec<Section>,
}

impl Report {
    pub fn new(dir: impl AsRef<Path>) -> Self {
        Self { dir: dir.as_ref().to_path_buf(), sections: Vec::new() }
    }

    pub fn add(&mut self, id: &str, title: &str, html: String) {
        self.sections.push(Section { id: id.to_string(), title: title.to_string(), html });
    }

    /// Write `index.html` into the report directory.
    pub fn write(&self) -> Result<PathBuf> {
        std::fs::create_dir_all(&self.dir)?;
        let mut html = String::from(
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n<title>truepos demo report</title>\n<style>\nbody{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}\ntable{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:3px 8px;text-align:right}th{background:#eee}\ntd:first-child,th:first-child{text-align:left}\nsvg{max-width:100%;height:auto}.pass{color:#070}.fail{color:#b00}\n</style></head><body>\n<h1>truepos demo report</h1>\n<p>Every capability run end to end on the virtual cell; each table compares what truepos recovered with the simulator's truth.</p>\n<ul>\n",
        );
        for s in &self.sections {
            html.push_str(&format!("<li><a href=\"#{}\">{}</a></li>\n", s.id, escape(&s.title)));
        }
        html.push_str("</ul>\n");
        for s in &self.sections {
            html.push_str(&format!(
                "<section id=\"{}\"><h2>{}</h2>\n{}\n</section>\n",
                s.id,
                escape(&s.title),
                s.html
            ));
        }
        html.push_str("</body></html>\n");
        let path = self.dir.join("index.html");
        truepos_io::atomic::write_atomic(&path, html.as_bytes())?;
        let summary = serde_json::to_vec_pretty(&self.summary())?;
        truepos_io::atomic::write_atomic(self.dir.join("summary.json"), &summary)?;
        Ok(path)
    }

    /// Every table of the report as data (`summary.json`): one entry per section with its
    /// tables, each a header and rows of the cells exactly as the report prints them. Two runs
    /// of the demo are compared by diffing this file.
    pub fn summary(&self) -> serde_json::Value {
        let sections: Vec<serde_json::Value> = self
            .sections
            .iter()
            .map(|s| {
                let tables: Vec<serde_json::Value> = parse_tables(&s.html)
                    .into_iter()
                    .map(|(header, rows)| serde_json::json!({ "header": header, "rows": rows }))
                    .collect();
                serde_json::json!({ "id": s.id, "title": s.title, "tables": tables })
            })
            .collect();
        serde_json::json!({ "sections": sections })
    }
}

/// The tables [`table`] wrote into a section's HTML, back as (header, rows) of unescaped cells.
fn parse_tables(html: &str) -> Vec<(Vec<String>, Vec<Vec<String>>)> {
    let mut out = Vec::new();
    for chunk in html.split("<table>").skip(1) {
        let body = chunk.split("</table>").next().unwrap_or("");
        let mut header = Vec::new();
        let mut rows = Vec::new();
        for row in body.split("<tr>").skip(1) {
            let row = row.split("</tr>").next().unwrap_or("");
            let mut cells = Vec::new();
            let mut is_header = false;
            for cell in row.split("<t").skip(1) {
                is_header |= cell.starts_with('h');
                let text = cell.split_once('>').map_or("", |(_, rest)| rest);
                let text = text.split("</t").next().unwrap_or("");
                cells.push(unescape(text));
            }
            if is_header {
                header = cells;
            } else {
                rows.push(cells);
            }
        }
        out.push((header, rows));
    }
    out
}

fn unescape(s: &str) -> String {
    s.replace("&quot;", "\"").replace("&gt;", ">").replace("&lt;", "<").replace("&amp;", "&")
}

/// HTML-escape text.
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// An HTML table from a header and rows of already formatted cells (escaped; cells reading
/// `pass` / `FAIL` are coloured).
pub fn table(header: &[&str], rows: &[Vec<String>]) -> String {
    let mut h = String::from("<table><tr>");
    for c in header {
        h.push_str(&format!("<th>{}</th>", escape(c)));
    }
    h.push_str("</tr>\n");
    for r in rows {
        h.push_str("<tr>");
        for c in r {
            // Verdict cells are coloured.
            let class = match c.as_str() {
                "pass" => " class=\"pass\"",
                "FAIL" | "fail" => " class=\"fail\"",
                _ => "",
            };
            h.push_str(&format!("<td{class}>{}</td>", escape(c)));
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
    h
}

/// How a series is drawn.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Style {
    Line,
    Points,
}

/// One data series of an [`xy_plot`].
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub style: Style,
}

impl Series {
    pub fn line(label: &str, points: Vec<(f64, f64)>) -> Self {
        Self { label: label.to_string(), points, style: Style::Line }
    }
    pub fn points(label: &str, points: Vec<(f64, f64)>) -> Self {
        Self { label: label.to_string(), points, style: Style::Points }
    }
}

const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

fn bounds(series: &[Series]) -> (f64, f64, f64, f64) {
    let mut b = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for s in series {
        for &(x, y) in &s.points {
            if x.is_finite() && y.is_finite() {
                b = (b.0.min(x), b.1.max(x), b.2.min(y), b.3.max(y));
            }
        }
    }
    if !b.0.is_finite() {
        return (0.0, 1.0, 0.0, 1.0);
    }
    let pad = |lo: f64, hi: f64| {
        let d = if hi > lo { (hi - lo) * 0.05 } else { lo.abs().max(1.0) * 0.05 };
        (lo - d, hi + d)
    };
    let (x0, x1) = pad(b.0, b.1);
    let (y0, y1) = pad(b.2, b.3);
    (x0, x1, y0, y1)
}

fn plot_err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow::anyhow!("plot: {e:?}")
}

/// A line/scatter plot as an SVG string.
pub fn xy_plot(title: &str, x_label: &str, y_label: &str, series: &[Series]) -> Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (760, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let (x0, x1, y0, y1) = bounds(series);
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(plot_err)?;
        chart.configure_mesh().x_desc(x_label).y_desc(y_label).draw().map_err(plot_err)?;
        for (i, s) in series.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            match s.style {
                Style::Line => {
                    chart
                        .draw_series(LineSeries::new(s.points.iter().copied(), color.stroke_width(2)))
                        .map_err(plot_err)?
                        .label(s.label.clone())
                        .legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 16, y)], color.stroke_width(2))
                        });
                }
                Style::Points => {
                    chart
                        .draw_series(s.points.iter().map(|&p| Circle::new(p, 2, color.filled())))
                        .map_err(plot_err)?
                        .label(s.label.clone())
                        .legend(move |(x, y)| Circle::new((x + 8, y), 3, color.filled()));
                }
            }
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(plot_err)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

/// Overlaid histograms of several value sets over common bins.
pub fn histogram(title: &str, x_label: &str, sets: &[(&str, &[f64])], bins: usize) -> Result<String> {
    let all: Vec<f64> = sets.iter().flat_map(|s| s.1.iter().copied()).filter(|v| v.is_finite()).collect();
    let lo = all.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = all.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let (lo, hi) = if lo.is_finite() && hi > lo { (lo, hi) } else { (0.0, 1.0) };
    let bins = bins.max(1);
    let w = (hi - lo) / bins as f64;
    let counts: Vec<Vec<usize>> = sets
        .iter()
        .map(|s| {
            let mut c = vec![0; bins];
            for v in s.1.iter().filter(|v| v.is_finite()) {
                let k = (((v - lo) / w) as usize).min(bins - 1);
                c[k] += 1;
            }
            c
        })
        .collect();
    let ymax = counts.iter().flatten().copied().max().unwrap_or(1).max(1) as f64;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (760, 380)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(lo..hi, 0.0..ymax * 1.1)
            .map_err(plot_err)?;
        chart.configure_mesh().x_desc(x_label).y_desc("count").draw().map_err(plot_err)?;
        for (i, (label, _)) in sets.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            let c = &counts[i];
            chart
                .draw_series(c.iter().enumerate().map(|(k, &n)| {
                    let x0 = lo + k as f64 * w;
                    Rectangle::new([(x0, 0.0), (x0 + w, n as f64)], color.mix(0.45).filled())
                }))
                .map_err(plot_err)?
                .label(label.to_string())
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 12, y + 5)], color.mix(0.45).filled())
                });
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(plot_err)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

/// A colour map of `values[j][i]` over `x` (i) and `y` (j) cell centres, with a legend of the range.
pub fn heatmap(title: &str, x: &[f64], y: &[f64], values: &[Vec<f64>], unit: &str) -> Result<String> {
    let lo = values.iter().flatten().cloned().fold(f64::INFINITY, f64::min);
    let hi = values.iter().flatten().cloned().fold(f64::NEG_INFINITY, f64::max);
    let span = if hi > lo { hi - lo } else { 1.0 };
    let dx = if x.len() > 1 { x[1] - x[0] } else { 1.0 };
    let dy = if y.len() > 1 { y[1] - y[0] } else { 1.0 };
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (760, 520)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let caption = format!("{title} ({lo:.3} … {hi:.3} {unit}, blue → red)");
        let x0 = x.first().copied().unwrap_or(0.0) - dx / 2.0;
        let x1 = x.last().copied().unwrap_or(1.0) + dx / 2.0;
        let y0 = y.first().copied().unwrap_or(0.0) - dy / 2.0;
        let y1 = y.last().copied().unwrap_or(1.0) + dy / 2.0;
        let mut chart = ChartBuilder::on(&root)
            .caption(caption, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(plot_err)?;
        chart.configure_mesh().x_desc("x (mm)").y_desc("y (mm)").disable_mesh().draw().map_err(plot_err)?;
        chart
            .draw_series(values.iter().enumerate().flat_map(|(j, row)| {
                row.iter().enumerate().map(move |(i, &v)| {
                    let t = ((v - lo) / span).clamp(0.0, 1.0);
                    let c = RGBColor(
                        (255.0 * t) as u8,
                        (80.0 * (1.0 - (2.0 * t - 1.0).abs())) as u8,
                        (255.0 * (1.0 - t)) as u8,
                    );
                    let (cx, cy) = (x[i], y[j]);
                    Rectangle::new(
                        [(cx - dx / 2.0, cy - dy / 2.0), (cx + dx / 2.0, cy + dy / 2.0)],
                        c.filled(),
                    )
                })
            }))
            .map_err(plot_err)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `summary.json` gives back every table exactly as [`table`] wrote it, escaped cells
    /// included, section by section.
    #[test]
    fn summary_round_trips_the_tables() {
        let mut r = Report::new("unused");
        let rows = vec![vec!["a <b> & \"c\"".to_string(), "1.25".into()], vec!["pass".into(), "FAIL".into()]];
        let html = format!("<p>text</p>{}<p>more</p>{}", table(&["name", "µm"], &rows), table(&["x"], &[]));
        r.add("s1", "Section", html);
        r.add("s2", "Empty", "<p>no tables</p>".into());
        let s = r.summary();
        let t = &s["sections"][0]["tables"];
        assert_eq!(t[0]["header"], serde_json::json!(["name", "µm"]));
        assert_eq!(t[0]["rows"], serde_json::json!([["a <b> & \"c\"", "1.25"], ["pass", "FAIL"]]));
        assert_eq!(t[1]["header"], serde_json::json!(["x"]));
        assert_eq!(t[1]["rows"], serde_json::json!([]));
        assert_eq!(s["sections"][1]["tables"], serde_json::json!([]));
        assert_eq!(s["sections"][1]["id"], "s2");
    }
}
