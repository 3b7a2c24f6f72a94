//! # truepos-report — the demo report
//!
//! The demo report: an `index.html` with a header (version, time, seed, machine, environment,
//! command line), the overall verdict and one summary row per capability, then one section per
//! capability with its verdict against truth, tables and inline SVG plots drawn with plotters'
//! SVG backend; and `summary.json` with the same content as data.
//!
//! Entry points: [`Report`] (collect sections and verdicts, write atomically), [`Header`],
//! [`Verdict`], [`xy_plot`] / [`xy_plot_equal`], [`histogram`], [`heatmap`], [`table`].
//!
//! Reruns are byte-identical apart from the generation time, which the caller passes in
//! ([`Header::generated_unix_s`]; the CLI takes it from `SOURCE_DATE_EPOCH` when set).

#![forbid(unsafe_code)]

mod error;

pub use error::{ReportError, Result};
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// One section of the report: its anchor id, its title and its HTML body.
pub struct Section {
    /// Anchor id of the section.
    pub id: String,
    /// Title of the section.
    pub title: String,
    /// HTML body of the section.
    pub html: String,
}

/// Who and what produced the report (printed at the top and in `summary.json`).
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Header {
    /// truepos version.
    pub version: String,
    /// Generation time, seconds since 1970-01-01 UTC.
    pub generated_unix_s: i64,
    /// The command line that produced the report.
    pub command_line: String,
    /// Random seed of the simulated cells.
    pub seed: u64,
    /// The machine(s) simulated.
    pub machine: String,
    /// Environment used (temperature, pressure, humidity).
    pub environment: String,
}

/// One capability's result against truth: a row of the summary table and the box at the top of
/// its section. Uncertainties are expanded, with the coverage factor written in the text.
///
/// The verdict follows ISO 14253-1 ([`Judgement`]): `pass` needs the expanded uncertainty below
/// the tolerance (a result whose uncertainty is as large as the tolerance proves nothing:
/// `inconclusive`), and under the guarded rule |error| + U ≤ tolerance. A capability that could
/// not run is `skipped` with its reason, never `pass`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Verdict {
    /// Section id this verdict belongs to.
    pub section: String,
    /// The capability judged (its name in the summary table).
    pub capability: String,
    /// What was measured.
    pub measured: String,
    /// The truth the result is compared with, in words.
    pub truth: String,
    /// The result, in words.
    pub result: String,
    /// Expanded uncertainty with its coverage factor and basis, in words (e.g. "U = 1.2 µm (k =
    /// 2) from …").
    pub uncertainty: String,
    /// Tolerance the result is judged against, with its reason, in words.
    pub tolerance_text: String,
    /// `pass`, `fail`, `inconclusive` or `skipped`.
    pub verdict: Outcome,
    /// Why the verdict is not `pass` (or what else it rests on).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// The decision rule applied.
    pub decision_rule: DecisionRule,
    /// The result's deviation from the truth (in `unit`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<f64>,
    /// Expanded uncertainty of `error` (k = `coverage_factor`, in `unit`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub expanded_uncertainty: Option<f64>,
    /// Coverage factor k of `expanded_uncertainty`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage_factor: Option<f64>,
    /// The tolerance on |error| (in `unit`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Unit of `error`, `expanded_uncertainty` and `tolerance`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<String>,
}

/// A verdict's outcome (`summary.json` `verdict`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Outcome {
    /// The result conforms.
    Pass,
    /// The result does not conform.
    Fail,
    /// The uncertainty is too large to decide.
    Inconclusive,
    /// The capability could not run (the reason is given).
    Skipped,
}

impl Outcome {
    /// The word the report prints.
    pub fn word(self) -> &'static str {
        match self {
            Outcome::Pass => "pass",
            Outcome::Fail => "FAIL",
            Outcome::Inconclusive => "inconclusive",
            Outcome::Skipped => "skipped",
        }
    }
}

/// ISO 14253-1 decision rules.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DecisionRule {
    /// Conformance when |error| ≤ tolerance (and U < tolerance: otherwise the result proves
    /// nothing).
    Simple,
    /// Conformance only when |error| + U ≤ tolerance; non-conformance only when |error| − U >
    /// tolerance; otherwise inconclusive.
    Guarded,
}

/// The numbers a capability is judged on.
#[derive(Debug, Clone, PartialEq)]
pub struct Judgement {
    /// Deviation of the result from the truth, in `unit`.
    pub error: f64,
    /// Expanded uncertainty of `error`, in `unit`.
    pub expanded_uncertainty: f64,
    /// The tolerance on |error|, in `unit`.
    pub tolerance: f64,
    /// The unit of the three numbers.
    pub unit: &'static str,
    /// The decision rule.
    pub rule: DecisionRule,
    /// Other conditions of the capability that failed (each makes the verdict `fail`).
    pub failures: Vec<String>,
    /// Why the uncertainty is not known (the verdict is then `inconclusive`).
    pub unknown: Option<String>,
}

impl Judgement {
    /// |error| against `tolerance` with expanded uncertainty `u` (k = 2) under `rule`.
    pub fn new(error: f64, u: f64, tolerance: f64, unit: &'static str, rule: DecisionRule) -> Judgement {
        Judgement {
            error,
            expanded_uncertainty: u,
            tolerance,
            unit,
            rule,
            failures: Vec::new(),
            unknown: None,
        }
    }

    /// A further condition: when `ok` is false the verdict is `fail` with `what` as a reason.
    pub fn require(mut self, ok: bool, what: impl Into<String>) -> Judgement {
        if !ok {
            self.failures.push(what.into());
        }
        self
    }

    /// A result whose uncertainty is not known: never `pass` (inconclusive, with `why`).
    pub fn unknown_uncertainty(
        error: f64,
        tolerance: f64,
        unit: &'static str,
        why: impl Into<String>,
    ) -> Judgement {
        Judgement {
            error,
            expanded_uncertainty: f64::NAN,
            tolerance,
            unit,
            rule: DecisionRule::Simple,
            failures: Vec::new(),
            unknown: None,
        }
        .require_known(why)
    }

    fn require_known(mut self, why: impl Into<String>) -> Judgement {
        self.unknown = Some(why.into());
        self
    }

    /// The outcome and its reason.
    pub fn decide(&self) -> (Outcome, Option<String>) {
        let (e, u, t) = (self.error.abs(), self.expanded_uncertainty, self.tolerance);
        if !self.failures.is_empty() {
            return (Outcome::Fail, Some(self.failures.join("; ")));
        }
        if let Some(why) = &self.unknown {
            return (Outcome::Inconclusive, Some(format!("the uncertainty is unknown: {why}")));
        }
        if !(e.is_finite() && u.is_finite() && t.is_finite()) {
            return (
                Outcome::Inconclusive,
                Some("the error or its uncertainty is not a finite number".into()),
            );
        }
        let unit = self.unit;
        match self.rule {
            DecisionRule::Simple => {
                if e > t {
                    (Outcome::Fail, Some(format!("|error| {e:.4} {unit} > tolerance {t} {unit}")))
                } else if u >= t {
                    (
                        Outcome::Inconclusive,
                        Some(format!("U = {u:.4} {unit} is not below the tolerance {t} {unit}: the result proves nothing")),
                    )
                } else {
                    (Outcome::Pass, None)
                }
            }
            DecisionRule::Guarded => {
                if e - u > t {
                    (Outcome::Fail, Some(format!("|error| − U = {:.4} {unit} > tolerance {t} {unit}", e - u)))
                } else if u >= t || e + u > t {
                    (
                        Outcome::Inconclusive,
                        Some(format!(
                            "|error| + U = {:.4} {unit} exceeds the tolerance {t} {unit} (guarded rule): neither conformance nor non-conformance is proven",
                            e + u
                        )),
                    )
                } else {
                    (Outcome::Pass, None)
                }
            }
        }
    }
}

impl Verdict {
    /// The verdict fields of a judged capability (texts empty: fill them with struct update
    /// syntax, `Verdict { section: …, ..Verdict::judged(j) }`).
    pub fn judged(j: Judgement) -> Verdict {
        let (verdict, reason) = j.decide();
        Verdict {
            section: String::new(),
            capability: String::new(),
            measured: String::new(),
            truth: String::new(),
            result: String::new(),
            uncertainty: String::new(),
            tolerance_text: String::new(),
            verdict,
            reason,
            decision_rule: j.rule,
            error: Some(j.error),
            expanded_uncertainty: j.expanded_uncertainty.is_finite().then_some(j.expanded_uncertainty),
            coverage_factor: Some(truepos_math::stats::COVERAGE_FACTOR),
            tolerance: Some(j.tolerance),
            unit: Some(j.unit.to_string()),
        }
    }

    /// A capability that could not run (missing data or device): `skipped`, with the reason.
    pub fn skipped(section: &str, capability: &str, reason: impl Into<String>) -> Verdict {
        let reason = reason.into();
        Verdict {
            section: section.into(),
            capability: capability.into(),
            measured: "—".into(),
            truth: "—".into(),
            result: format!("not run: {reason}"),
            uncertainty: "—".into(),
            tolerance_text: "—".into(),
            verdict: Outcome::Skipped,
            reason: Some(reason),
            decision_rule: DecisionRule::Simple,
            error: None,
            expanded_uncertainty: None,
            coverage_factor: None,
            tolerance: None,
            unit: None,
        }
    }
}

/// `summary.json`'s `overall`: `pass` only when every verdict passes; `fail` when any fails;
/// otherwise (inconclusive or skipped ones, or none at all) `incomplete`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Overall {
    /// Every verdict passes.
    Pass,
    /// At least one verdict fails.
    Fail,
    /// No verdict fails, but some are inconclusive or skipped (or there are none).
    Incomplete,
}

/// UTC calendar date and time `YYYY-MM-DD hh:mm:ss UTC` of a Unix time.
pub fn utc_string(unix_s: i64) -> String {
    truepos_math::time::UtcDateTime::from_unix(unix_s).human()
}

const CSS: &str = "body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222;line-height:1.45}
table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #999;padding:3px 8px;text-align:left;vertical-align:top}thead th{background:#eee}
td.num,th.num{text-align:right;font-variant-numeric:tabular-nums}tbody th{font-weight:normal}caption{text-align:left;font-weight:600;padding:0 0 .3em}
.wrap{overflow-x:auto;max-width:100%}
figure{margin:1em 0}figure svg{max-width:100%;height:auto;display:block}figcaption{font-size:.95em;color:#333}
.legend{list-style:none;padding:0;margin:.3em 0;display:flex;flex-wrap:wrap;gap:1.2em}.swatch{display:inline-block;width:1.2em;height:.8em;margin-right:.4em;vertical-align:middle;border:1px solid #555}
.pass{color:#065f06;font-weight:bold}.incomplete{color:#6b4a00;font-weight:bold}.fail{color:#a00000;font-weight:bold}
.overall{font-size:1.3em;padding:.5em 1em;border:2px solid currentColor;display:inline-block}
dl.header{display:grid;grid-template-columns:max-content 1fr;gap:.2em 1em}dl.header dt{font-weight:bold}dl.header dd{margin:0;overflow-wrap:anywhere}
.verdict td,.verdict th{text-align:left}
.banner{border:2px dashed #6b4a00;background:#fff8e6;padding:.4em .8em;font-weight:bold;display:inline-block;margin-left:1em}
.doccontrol td.fill{min-width:14em;height:1.6em}
@media print{body{max-width:none;margin:0;font-size:10pt;color:#000}nav{display:none}section{break-before:page}figure,.verdict{break-inside:avoid}tr{break-inside:avoid}.summary table{font-size:8.5pt;width:100%}.summary .verdict{break-inside:auto}.summary td,.summary th{padding:2px 4px}a{color:#000;text-decoration:none}.wrap{overflow:visible}h1,h2,h3,caption{break-after:avoid}h2+*,h3+*{break-before:avoid}p{orphans:3;widows:3}}
";

/// The page box of a printed report: its ID at the bottom left of every page and "page x of y"
/// at the bottom right (CSS page margin boxes).
fn print_css(report_id: &str) -> String {
    format!(
        "@page{{size:A4;margin:16mm 14mm 18mm;@bottom-left{{content:\"truepos report {report_id} — simulated data, not a calibration certificate\";font-size:8pt}}@bottom-right{{content:\"page \" counter(page) \" of \" counter(pages);font-size:8pt}}}}\n"
    )
}

/// FNV-1a (64 bit): a stable short fingerprint of the report's content for its ID.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes
        .iter()
        .fold(0xcbf2_9ce4_8422_2325_u64, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3))
}

/// A report under construction.
pub struct Report {
    /// The directory the report and its files are written to.
    pub dir: PathBuf,
    /// Who and what produced the report.
    pub header: Header,
    sections: Vec<Section>,
    verdicts: Vec<Verdict>,
}

impl Report {
    /// An empty report writing to `dir`.
    pub fn new(dir: impl AsRef<Path>) -> Self {
        Self {
            dir: dir.as_ref().to_path_buf(),
            header: Header::default(),
            sections: Vec::new(),
            verdicts: Vec::new(),
        }
    }

    /// Append a section.
    pub fn add(&mut self, id: &str, title: &str, html: String) {
        self.sections.push(Section { id: id.to_string(), title: title.to_string(), html });
    }

    /// Record a capability's verdict against truth (one summary row; shown at the top of its
    /// section).
    pub fn verdict(&mut self, v: Verdict) {
        self.verdicts.push(v);
    }

    /// The overall verdict ([`Overall`]).
    pub fn overall(&self) -> Overall {
        if self.verdicts.iter().any(|v| v.verdict == Outcome::Fail) {
            Overall::Fail
        } else if !self.verdicts.is_empty() && self.verdicts.iter().all(|v| v.verdict == Outcome::Pass) {
            Overall::Pass
        } else {
            Overall::Incomplete
        }
    }

    /// True when the overall verdict is `pass`.
    pub fn overall_pass(&self) -> bool {
        self.overall() == Overall::Pass
    }

    /// The verdicts recorded so far.
    pub fn verdicts(&self) -> &[Verdict] {
        &self.verdicts
    }

    /// The report's ID: `TP-YYYYMMDD-` and a fingerprint of its verdicts and tables (two reports
    /// with the same ID have the same content).
    pub fn report_id(&self) -> String {
        let content = serde_json::json!({ "capabilities": self.verdicts, "sections": self.sections.iter().map(|s| (&s.id, &s.html)).collect::<Vec<_>>() });
        let date = utc_string(self.header.generated_unix_s);
        let ymd: String = date.chars().take(10).filter(|c| c.is_ascii_digit()).collect();
        format!("TP-{ymd}-{:08X}", fnv1a(content.to_string().as_bytes()) >> 32)
    }

    /// The whole `index.html`.
    pub fn html(&self) -> String {
        let h = &self.header;
        let overall = self.overall();
        let named = |o: Outcome| -> Vec<&str> {
            self.verdicts.iter().filter(|v| v.verdict == o).map(|v| v.capability.as_str()).collect()
        };
        let (failed, open, skipped) =
            (named(Outcome::Fail), named(Outcome::Inconclusive), named(Outcome::Skipped));
        let mut html = format!(
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>truepos demo report</title>\n<style>\n{CSS}{}</style></head><body>\n<header>\n<h1>truepos demo report</h1>\n<dl class=\"header\">\n<dt>truepos version</dt><dd>{}</dd>\n<dt>generated</dt><dd>{}</dd>\n<dt>command line</dt><dd><code>{}</code></dd>\n<dt>seed</dt><dd>{}</dd>\n<dt>machines</dt><dd>{}</dd>\n<dt>environment</dt><dd>{}</dd>\n</dl>\n</header>\n<main>\n<h2 id=\"verdict\">Overall verdict</h2>\n<p class=\"overall {}\">{}</p><p class=\"banner\" role=\"note\">Simulated data — not a calibration certificate</p>\n",
            print_css(&self.report_id()),
            escape(&h.version),
            utc_string(h.generated_unix_s),
            escape(&h.command_line),
            h.seed,
            escape(&h.machine),
            escape(&h.environment),
            match overall {
                Overall::Pass => "pass",
                Overall::Fail => "fail",
                Overall::Incomplete => "incomplete",
            },
            match overall {
                Overall::Pass => format!(
                    "PASS — all {} capabilities within tolerance against the simulator's truth, each with U below its tolerance",
                    self.verdicts.len()
                ),
                Overall::Fail => escape(&format!("FAIL — outside tolerance: {}", failed.join(", "))),
                Overall::Incomplete => escape(&format!(
                    "INCOMPLETE — not every capability was shown to pass (inconclusive: {}; skipped: {})",
                    if open.is_empty() { "none".into() } else { open.join(", ") },
                    if skipped.is_empty() { "none".into() } else { skipped.join(", ") }
                )),
            },
        );
        html.push_str(&self.document_control());
        html.push_str("<p>Every capability runs end to end on the virtual cell (or on NIST reference data for fitting); each result is compared with the truth the simulator used, which truepos never sees. Uncertainties are expanded uncertainties U with the coverage factor k stated (k = 2: about 95 % coverage for a normal distribution).</p>\n");
        let rows: Vec<Vec<String>> = self
            .verdicts
            .iter()
            .map(|v| {
                vec![
                    v.capability.clone(),
                    v.measured.clone(),
                    v.result.clone(),
                    v.uncertainty.clone(),
                    v.tolerance_text.clone(),
                    v.verdict.word().into(),
                ]
            })
            .collect();
        html.push_str("<h2 id=\"summary\">Summary</h2>\n");
        html.push_str("<div class=\"summary\">");
        html.push_str(&table_left(
            "One row per capability",
            &["capability", "measured", "result", "uncertainty", "tolerance", "verdict"],
            &rows,
        ));
        html.push_str("</div>\n");
        html.push_str(&self.traceability());
        html.push_str("<nav aria-label=\"Sections\"><h2>Sections</h2><ul>\n");
        for s in &self.sections {
            html.push_str(&format!("<li><a href=\"#{}\">{}</a></li>\n", s.id, escape(&s.title)));
        }
        html.push_str("</ul></nav>\n");
        for s in &self.sections {
            let mut boxes = String::new();
            for v in self.verdicts.iter().filter(|v| v.section == s.id) {
                boxes.push_str(&verdict_box(v));
            }
            html.push_str(&format!(
                "<section id=\"{}\" aria-labelledby=\"{}-h\"><h2 id=\"{}-h\">{}</h2>\n{}{}\n</section>\n",
                s.id,
                s.id,
                s.id,
                escape(&s.title),
                boxes,
                s.html
            ));
        }
        html.push_str("</main>\n</body></html>\n");
        html
    }

    /// The document-control block: report ID, version and build, date, decision rule, and the
    /// fields a quality engineer fills in (operator, approval, signature, date).
    fn document_control(&self) -> String {
        let h = &self.header;
        let rows = vec![
            vec!["report ID".to_string(), self.report_id()],
            vec!["software".to_string(), format!("truepos {}", h.version)],
            vec!["generated".to_string(), utc_string(h.generated_unix_s)],
            vec![
                "decision rule".to_string(),
                "ISO 14253-1, per capability as stated in its section; expanded uncertainties with k = 2; pass requires U < tolerance".to_string(),
            ],
            vec!["status of the data".to_string(), "simulated — not a calibration certificate".to_string()],
        ];
        let mut t = table_left("Identification", &["item", "value"], &rows);
        t.push_str("<div class=\"wrap\"><table class=\"verdict doccontrol\"><caption>Review and approval (to be completed by hand)</caption><thead><tr><th scope=\"col\">role</th><th scope=\"col\">name</th><th scope=\"col\">signature</th><th scope=\"col\">date</th></tr></thead>\n<tbody>\n");
        for role in ["operator", "reviewed by", "approved by"] {
            t.push_str(&format!("<tr><th scope=\"row\">{role}</th><td class=\"fill\"></td><td class=\"fill\"></td><td class=\"fill\"></td></tr>\n"));
        }
        t.push_str("</tbody></table></div>\n");
        format!("<h2 id=\"document-control\">Document control</h2>\n{t}")
    }

    /// What each capability's truth is and what it is traceable to.
    fn traceability(&self) -> String {
        let rows: Vec<Vec<String>> = self
            .verdicts
            .iter()
            .map(|v| {
                let to = match v.section.as_str() {
                    "fit" => "NIST's certified least-squares fits (NIST algorithm-testing service, ASME B89.4.10): an external reference computed in extended precision",
                    "air" => "NIST's published refractive-index values (Ciddor equation): an external reference",
                    _ => "the simulator's own truth: exact by construction, traceable to no physical standard; it shows that the method recovers what the simulated machine did, not what a real machine does",
                };
                vec![v.capability.clone(), v.truth.clone(), to.to_string()]
            })
            .collect();
        format!(
            "<h2 id=\"traceability\">Traceability</h2>\n<p>Each result is compared with a truth. What that truth is, and what it is traceable to:</p>\n{}",
            table(&["capability", "truth", "traceable to"], &rows)
        )
    }

    /// Write `index.html` and `summary.json` into the report directory.
    pub fn write(&self) -> Result<PathBuf> {
        std::fs::create_dir_all(&self.dir)?;
        let path = self.dir.join("index.html");
        truepos_io::atomic::write_atomic(&path, self.html().as_bytes())?;
        let summary = serde_json::to_vec_pretty(&self.summary())?;
        truepos_io::atomic::write_atomic(self.dir.join("summary.json"), &summary)?;
        Ok(path)
    }

    /// The report as data (`summary.json`): the header, the overall verdict, one verdict per
    /// capability, and one entry per section with its tables, each a header and rows of the
    /// cells exactly as the report prints them. Two runs of the demo are compared by diffing
    /// this file.
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
        serde_json::json!({
            "header": {
                "version": self.header.version,
                "generated_utc": utc_string(self.header.generated_unix_s),
                "generated_unix_s": self.header.generated_unix_s,
                "command_line": self.header.command_line,
                "seed": self.header.seed,
                "machine": self.header.machine,
                "environment": self.header.environment,
            },
            "report_id": self.report_id(),
            "overall": self.overall(),
            "capabilities": self.verdicts,
            "sections": sections,
        })
    }
}

fn decision_rule_text(r: DecisionRule) -> &'static str {
    match r {
        DecisionRule::Simple => "simple acceptance (ISO 14253-1), with U < tolerance required; k = 2",
        DecisionRule::Guarded => "guarded acceptance (ISO 14253-1): |error| + U ≤ tolerance; k = 2",
    }
}

fn verdict_box(v: &Verdict) -> String {
    let rows = vec![
        vec!["measured".to_string(), v.measured.clone()],
        vec!["truth".to_string(), v.truth.clone()],
        vec!["result".to_string(), v.result.clone()],
        vec!["uncertainty".to_string(), v.uncertainty.clone()],
        vec!["tolerance".to_string(), v.tolerance_text.clone()],
        vec!["decision rule".to_string(), decision_rule_text(v.decision_rule).to_string()],
        vec!["verdict".to_string(), v.verdict.word().to_string()],
    ];
    let mut rows = rows;
    if let Some(r) = &v.reason {
        rows.push(vec!["reason".to_string(), r.clone()]);
    }
    let mut h = format!(
        "<table class=\"verdict\"><caption>{}: verdict against truth</caption><thead><tr><th scope=\"col\">item</th><th scope=\"col\">value</th></tr></thead><tbody>\n",
        escape(&v.capability)
    );
    for r in rows {
        let class = match r[1].as_str() {
            "pass" => " class=\"pass\"",
            "FAIL" => " class=\"fail\"",
            "inconclusive" | "skipped" => " class=\"incomplete\"",
            _ => "",
        };
        h.push_str(&format!(
            "<tr><th scope=\"row\">{}</th><td{class}>{}</td></tr>\n",
            escape(&r[0]),
            escape(&r[1])
        ));
    }
    h.push_str("</tbody></table>\n");
    h
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
            let mut rest = row;
            while let Some(i) = rest.find("<t") {
                let tag = &rest[i + 2..];
                let kind = tag.chars().next().unwrap_or(' ');
                let after = tag.get(1..).unwrap_or("");
                if !(kind == 'h' || kind == 'd') || !(after.starts_with('>') || after.starts_with(' ')) {
                    rest = tag;
                    continue;
                }
                let text = after.split_once('>').map_or("", |(_, r)| r);
                let end = text.find("</t").unwrap_or(text.len());
                if kind == 'h' && after.contains("scope=\"col\"") {
                    is_header = true;
                }
                if kind == 'h' && after.starts_with('>') {
                    is_header = true;
                }
                cells.push(unescape(&text[..end]));
                rest = &text[end..];
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

fn table_left(caption: &str, header: &[&str], rows: &[Vec<String>]) -> String {
    let t = table(header, rows);
    t.replacen("<table>", &format!("<table class=\"verdict\"><caption>{}</caption>", escape(caption)), 1)
}

/// Whether a cell reads as a number (or a tuple of numbers, or a dash for "none"): such cells
/// are right-aligned so that their digits line up; text stays left-aligned.
fn is_numeric_cell(c: &str) -> bool {
    let c = c.trim();
    c.chars().any(|ch| ch.is_ascii_digit())
        && c.chars().all(|ch| ch.is_ascii_digit() || " .,()+-−×eE%⁻⁰¹²³⁴⁵⁶⁷⁸⁹".contains(ch))
        || c == "—"
}

/// An HTML table from a header and rows of already formatted cells (escaped; `<thead>` with
/// column headers, the first cell of each row a row header; cells reading `pass` / `FAIL` are
/// coloured; columns whose every cell is a number are right-aligned, the rest left-aligned).
/// Wrapped so a wide table scrolls on a narrow screen instead of the page.
pub fn table(header: &[&str], rows: &[Vec<String>]) -> String {
    let numeric: Vec<bool> = (0..header.len())
        .map(|i| {
            i > 0
                && rows.iter().any(|r| r.get(i).is_some_and(|c| c != "—"))
                && rows.iter().all(|r| r.get(i).is_none_or(|c| is_numeric_cell(c)))
        })
        .collect();
    let num = |i: usize| numeric.get(i).copied().unwrap_or(false);
    let mut h = String::from("<div class=\"wrap\"><table><thead><tr>");
    for (i, c) in header.iter().enumerate() {
        let class = if num(i) { " class=\"num\"" } else { "" };
        h.push_str(&format!("<th scope=\"col\"{class}>{}</th>", escape(c)));
    }
    h.push_str("</tr></thead>\n<tbody>\n");
    for r in rows {
        h.push_str("<tr>");
        for (i, c) in r.iter().enumerate() {
            let class = match c.as_str() {
                "pass" => " class=\"pass\"",
                "FAIL" | "fail" => " class=\"fail\"",
                "inconclusive" | "skipped" => " class=\"incomplete\"",
                _ if num(i) => " class=\"num\"",
                _ => "",
            };
            if i == 0 {
                h.push_str(&format!("<th scope=\"row\"{class}>{}</th>", escape(c)));
            } else {
                h.push_str(&format!("<td{class}>{}</td>", escape(c)));
            }
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</tbody></table></div>\n");
    h
}

/// How a series is drawn.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Style {
    /// A line through the points.
    Line,
    /// The points as markers.
    Points,
}

/// One data series of an [`xy_plot`].
pub struct Series {
    /// Legend label.
    pub label: String,
    /// The (x, y) points, in the plot's units.
    pub points: Vec<(f64, f64)>,
    /// How the series is drawn.
    pub style: Style,
}

impl Series {
    /// A series drawn as a line.
    pub fn line(label: &str, points: Vec<(f64, f64)>) -> Self {
        Self { label: label.to_string(), points, style: Style::Line }
    }
    /// A series drawn as markers.
    pub fn points(label: &str, points: Vec<(f64, f64)>) -> Self {
        Self { label: label.to_string(), points, style: Style::Points }
    }
}

/// Colour-blind-safe palette (Okabe–Ito), dark enough against white.
const PALETTE: [RGBColor; 6] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(86, 180, 233),
    RGBColor(230, 159, 0),
];

/// Chart text sizes (px in the 760 px wide drawing; the figure scales down only on screens
/// narrower than that).
const CAPTION_PX: u32 = 20;
const LABEL_PX: u32 = 15;
/// Radius of a point marker: large enough to see on paper at 70 % scale.
const MARKER_PX: u32 = 3;

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

fn plot_err<E: std::fmt::Debug>(e: E) -> ReportError {
    ReportError::Plot(format!("{e:?}"))
}

fn rgb(c: RGBColor) -> String {
    format!("#{:02x}{:02x}{:02x}", c.0, c.1, c.2)
}

/// Round to 4 significant digits for text alternatives.
fn sig(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let mag = v.abs().log10().floor() as i32;
    let dec = (3 - mag).clamp(0, 9) as usize;
    format!("{v:.dec$}").replace('-', "\u{2212}")
}

/// Tick label for `v` on an axis whose labels are about `step` apart: as many decimals as the
/// step needs, no "−0", and the typographic minus sign (U+2212) that the report's text uses, so
/// that a figure and the table beside it write negative numbers the same way.
fn tick_label(v: f64, step: f64) -> String {
    let dec =
        if step > 0.0 && step.is_finite() { (-step.log10().floor()).clamp(0.0, 9.0) as usize } else { 3 };
    let s = format!("{v:.dec$}");
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        return s[1..].to_string();
    }
    s.replace('-', "\u{2212}")
}

/// The label formatter of an axis over `lo..hi` with about `n` labels (see [`tick_label`]).
fn ticks(lo: f64, hi: f64, n: usize) -> impl Fn(&f64) -> String {
    let step = (hi - lo).abs() / n.max(1) as f64;
    move |v: &f64| tick_label(*v, step)
}

/// Number of tick labels plotters is asked for on each axis.
const N_TICKS: usize = 10;

/// Wrap a plotters SVG as an accessible figure: `role="img"` with a `<title>`, the legend as
/// HTML below the drawing (never over the data), and a caption that is the text alternative.
fn figure(svg: &str, title: &str, legend: &[(String, RGBColor)], alt: &str) -> String {
    let svg = svg.replacen("<svg ", &format!("<svg role=\"img\" aria-label=\"{}\" ", escape(title)), 1);
    let svg = match svg.find('>') {
        Some(i) => format!("{}<title>{}</title>{}", &svg[..=i], escape(title), &svg[i + 1..]),
        None => svg,
    };
    let mut h = format!("<figure>\n{svg}\n");
    if !legend.is_empty() {
        h.push_str("<ul class=\"legend\" aria-label=\"legend\">");
        for (label, c) in legend {
            h.push_str(&format!(
                "<li><span class=\"swatch\" style=\"background:{}\"></span>{}</li>",
                rgb(*c),
                escape(label)
            ));
        }
        h.push_str("</ul>\n");
    }
    h.push_str(&format!("<figcaption>{}</figcaption>\n</figure>\n", escape(alt)));
    h
}

fn series_alt(x_label: &str, y_label: &str, series: &[Series]) -> String {
    let parts: Vec<String> = series
        .iter()
        .map(|s| {
            let b = bounds(std::slice::from_ref(s));
            let (xs, ys): (Vec<f64>, Vec<f64>) = s.points.iter().copied().unzip();
            let lo = |v: &[f64]| v.iter().copied().filter(|x| x.is_finite()).fold(f64::INFINITY, f64::min);
            let hi =
                |v: &[f64]| v.iter().copied().filter(|x| x.is_finite()).fold(f64::NEG_INFINITY, f64::max);
            let _ = b;
            format!(
                "“{}”: {} points, {x_label} {} to {}, {y_label} {} to {}",
                s.label,
                s.points.len(),
                sig(lo(&xs)),
                sig(hi(&xs)),
                sig(lo(&ys)),
                sig(hi(&ys))
            )
        })
        .collect();
    format!("Text alternative: {}.", parts.join("; "))
}

/// A line/scatter plot as an accessible SVG figure (legend and text alternative in HTML).
pub fn xy_plot(title: &str, x_label: &str, y_label: &str, series: &[Series]) -> Result<String> {
    xy_plot_impl(title, x_label, y_label, series, false)
}

/// As [`xy_plot`] with one data unit the same length on both axes (paths in a plane: a circle
/// is drawn as a circle).
pub fn xy_plot_equal(title: &str, x_label: &str, y_label: &str, series: &[Series]) -> Result<String> {
    xy_plot_impl(title, x_label, y_label, series, true)
}

fn xy_plot_impl(title: &str, x_label: &str, y_label: &str, series: &[Series], equal: bool) -> Result<String> {
    let mut svg = String::new();
    let (w, h) = (760u32, if equal { 620u32 } else { 420u32 });
    let (xa, ya, margin, cap) = (50u32, 90u32, 12u32, 40u32);
    {
        let root = SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let (mut x0, mut x1, mut y0, mut y1) = bounds(series);
        if equal {
            // Plot area in pixels; widen the range that is short of the common mm/px scale.
            let pw = f64::from(w - ya - 2 * margin);
            let ph = f64::from(h - xa - 2 * margin - cap);
            let s = ((x1 - x0) / pw).max((y1 - y0) / ph);
            let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
            (x0, x1, y0, y1) = (cx - s * pw / 2.0, cx + s * pw / 2.0, cy - s * ph / 2.0, cy + s * ph / 2.0);
        }
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", CAPTION_PX))
            .margin(margin)
            .x_label_area_size(xa)
            .y_label_area_size(ya)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(plot_err)?;
        let (fx, fy) = (ticks(x0, x1, N_TICKS), ticks(y0, y1, N_TICKS));
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .x_labels(N_TICKS)
            .y_labels(N_TICKS)
            .x_label_formatter(&fx)
            .y_label_formatter(&fy)
            .label_style(("sans-serif", LABEL_PX))
            .axis_desc_style(("sans-serif", LABEL_PX))
            .draw()
            .map_err(plot_err)?;
        // Lines first, then point markers on top, so that a fitted line never hides the
        // measured points it was fitted to.
        let order = series.iter().enumerate().filter(|(_, s)| s.style == Style::Line);
        for (i, s) in order.chain(series.iter().enumerate().filter(|(_, s)| s.style == Style::Points)) {
            let color = PALETTE[i % PALETTE.len()];
            match s.style {
                Style::Line => {
                    chart
                        .draw_series(LineSeries::new(s.points.iter().copied(), color.stroke_width(2)))
                        .map_err(plot_err)?;
                }
                Style::Points => {
                    chart
                        .draw_series(s.points.iter().map(|&p| Circle::new(p, MARKER_PX, color.filled())))
                        .map_err(plot_err)?;
                }
            }
        }
        root.present().map_err(plot_err)?;
    }
    let legend: Vec<(String, RGBColor)> =
        series.iter().enumerate().map(|(i, s)| (s.label.clone(), PALETTE[i % PALETTE.len()])).collect();
    let mut alt = series_alt(x_label, y_label, series);
    if equal {
        alt.push_str(" Both axes have the same scale.");
    }
    Ok(figure(&svg, title, &legend, &alt))
}

/// A vertical reference line across a histogram: a tolerance limit, a nominal value.
#[derive(Clone, Copy, Debug)]
pub struct Mark<'a> {
    /// Legend text, e.g. "tolerance 5 µm".
    pub label: &'a str,
    /// Position on the value axis, in the histogram's unit.
    pub value: f64,
}

/// The bin range of a histogram: `range` when given and non-empty, else the finite values' own
/// range widened to take in every mark, so that a tolerance is always on the drawing.
fn histogram_range(values: &[f64], range: Option<(f64, f64)>, marks: &[Mark]) -> (f64, f64) {
    if let Some((a, b)) = range.filter(|(a, b)| b > a && a.is_finite() && b.is_finite()) {
        return (a, b);
    }
    let finite = values.iter().chain(marks.iter().map(|m| &m.value)).copied().filter(|v| v.is_finite());
    let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| (l.min(v), h.max(v)));
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    // Values that start near zero (errors, magnitudes) keep zero as the left edge.
    let lo = if lo >= 0.0 && lo <= 0.5 * hi { 0.0 } else { lo };
    let pad = if hi > lo { 0.03 * (hi - lo) } else { lo.abs().max(1.0) * 0.05 };
    (if lo == 0.0 { 0.0 } else { lo - pad }, hi + pad)
}

/// Overlaid histograms of several value sets over common bins from `range` (or the data's own
/// range, widened to take in the marks, when `None`), with each [`Mark`] drawn as a dashed
/// vertical line named in the legend. Give each histogram its own range unless two are meant to
/// be compared bin for bin.
pub fn histogram(
    title: &str,
    x_label: &str,
    sets: &[(&str, &[f64])],
    bins: usize,
    range: Option<(f64, f64)>,
    marks: &[Mark],
) -> Result<String> {
    let all: Vec<f64> = sets.iter().flat_map(|s| s.1.iter().copied()).filter(|v| v.is_finite()).collect();
    let (lo, hi) = histogram_range(&all, range, marks);
    let bins = bins.max(1);
    let w = (hi - lo) / bins as f64;
    let counts: Vec<Vec<usize>> = sets
        .iter()
        .map(|s| {
            let mut c = vec![0; bins];
            for v in s.1.iter().filter(|v| v.is_finite()) {
                let k = (((v - lo) / w).max(0.0) as usize).min(bins - 1);
                c[k] += 1;
            }
            c
        })
        .collect();
    let ymax = counts.iter().flatten().copied().max().unwrap_or(1).max(1) as f64;
    let mark_colour = RGBColor(0, 0, 0);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (760, 380)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", CAPTION_PX))
            .margin(12)
            .margin_right(24)
            .x_label_area_size(50)
            .y_label_area_size(70)
            .build_cartesian_2d(lo..hi, 0.0..ymax * 1.1)
            .map_err(plot_err)?;
        let fx = ticks(lo, hi, N_TICKS);
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc("count")
            .x_labels(N_TICKS)
            .x_label_formatter(&fx)
            // Counts are whole numbers: no "70.0".
            .y_label_formatter(&|v| if v.fract() == 0.0 { format!("{v:.0}") } else { format!("{v:.1}") })
            .label_style(("sans-serif", LABEL_PX))
            .axis_desc_style(("sans-serif", LABEL_PX))
            .draw()
            .map_err(plot_err)?;
        for (i, c) in counts.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            chart
                .draw_series(c.iter().enumerate().filter(|(_, &n)| n > 0).map(|(k, &n)| {
                    let x0 = lo + k as f64 * w;
                    Rectangle::new([(x0, 0.0), (x0 + w, n as f64)], color.mix(0.55).filled())
                }))
                .map_err(plot_err)?;
        }
        for m in marks.iter().filter(|m| m.value.is_finite() && m.value >= lo && m.value <= hi) {
            chart
                .draw_series(DashedLineSeries::new(
                    [(m.value, 0.0), (m.value, ymax * 1.1)],
                    8,
                    5,
                    mark_colour.stroke_width(2),
                ))
                .map_err(plot_err)?;
        }
        root.present().map_err(plot_err)?;
    }
    let mut legend: Vec<(String, RGBColor)> =
        sets.iter().enumerate().map(|(i, s)| (s.0.to_string(), PALETTE[i % PALETTE.len()])).collect();
    legend.extend(marks.iter().map(|m| (format!("{} (dashed line)", m.label), mark_colour)));
    let parts: Vec<String> = sets
        .iter()
        .map(|(label, v)| {
            let f: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
            let mean = f.iter().sum::<f64>() / f.len().max(1) as f64;
            let max = f.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            format!("“{label}”: {} values, mean {}, max {}", f.len(), sig(mean), sig(max))
        })
        .collect();
    let mut alt = format!(
        "Text alternative: histogram of {x_label}, {bins} bins from {} to {}; {}.",
        sig(lo),
        sig(hi),
        parts.join("; ")
    );
    for m in marks {
        alt.push_str(&format!(" {} at {}.", m.label, sig(m.value)));
    }
    Ok(figure(&svg, title, &legend, &alt))
}

/// Diverging colour for `t` in [-1, 1]: blue (−) through white (0) to red (+).
fn diverging(t: f64) -> RGBColor {
    let t = t.clamp(-1.0, 1.0);
    let (r, g, b) = if t < 0.0 {
        let a = -t;
        (255.0 * (1.0 - a) + 33.0 * a, 255.0 * (1.0 - a) + 102.0 * a, 255.0 * (1.0 - a) + 172.0 * a)
    } else {
        (255.0 * (1.0 - t) + 178.0 * t, 255.0 * (1.0 - t) + 24.0 * t, 255.0 * (1.0 - t) + 43.0 * t)
    };
    RGBColor(r as u8, g as u8, b as u8)
}

/// A colour map of `values[j][i]` over `x` (i) and `y` (j) cell centres (equal aspect), with a
/// colour bar over the data's own range labelled with its unit (white = 0, blue negative, red
/// positive, full colour at the largest magnitude).
pub fn heatmap(title: &str, x: &[f64], y: &[f64], values: &[Vec<f64>], unit: &str) -> Result<String> {
    let lo = values.iter().flatten().cloned().fold(f64::INFINITY, f64::min);
    let hi = values.iter().flatten().cloned().fold(f64::NEG_INFINITY, f64::max);
    let m = lo.abs().max(hi.abs());
    let m = if m > 0.0 && m.is_finite() { m } else { 1.0 };
    let dx = if x.len() > 1 { x[1] - x[0] } else { 1.0 };
    let dy = if y.len() > 1 { y[1] - y[0] } else { 1.0 };
    let x0 = x.first().copied().unwrap_or(0.0) - dx / 2.0;
    let x1 = x.last().copied().unwrap_or(1.0) + dx / 2.0;
    let y0 = y.first().copied().unwrap_or(0.0) - dy / 2.0;
    let y1 = y.last().copied().unwrap_or(1.0) + dy / 2.0;
    let (w, bar_w) = (760u32, 120u32);
    // Height for equal aspect of the map area.
    let map_w = f64::from(w - bar_w - 80 - 24);
    let map_h = (map_w * (y1 - y0) / (x1 - x0)).clamp(150.0, 700.0);
    let h = map_h as u32 + 50 + 24 + 40;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let (map_area, bar_area) = root.split_horizontally(w - bar_w);
        let mut chart = ChartBuilder::on(&map_area)
            .caption(title, ("sans-serif", CAPTION_PX))
            .margin(12)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(plot_err)?;
        let (fx, fy) = (ticks(x0, x1, N_TICKS), ticks(y0, y1, N_TICKS));
        chart
            .configure_mesh()
            .x_desc("x (mm)")
            .y_desc("y (mm)")
            .x_labels(N_TICKS)
            .y_labels(N_TICKS)
            .x_label_formatter(&fx)
            .y_label_formatter(&fy)
            .label_style(("sans-serif", LABEL_PX))
            .axis_desc_style(("sans-serif", LABEL_PX))
            .disable_mesh()
            .draw()
            .map_err(plot_err)?;
        chart
            .draw_series(values.iter().enumerate().flat_map(|(j, row)| {
                row.iter().enumerate().map(move |(i, &v)| {
                    let (cx, cy) = (x[i], y[j]);
                    Rectangle::new(
                        [(cx - dx / 2.0, cy - dy / 2.0), (cx + dx / 2.0, cy + dy / 2.0)],
                        diverging(v / m).filled(),
                    )
                })
            }))
            .map_err(plot_err)?;
        // The colour bar spans the data's own range (its ends are the smallest and largest
        // value), coloured on the same scale as the map: white is zero wherever it falls.
        let (b0, b1) = if hi > lo { (lo, hi) } else { (lo - 0.5 * m, lo + 0.5 * m) };
        let mut bar = ChartBuilder::on(&bar_area)
            .margin_top(12 + CAPTION_PX + 10)
            .margin_bottom(12)
            .margin_left(8)
            .margin_right(4)
            .x_label_area_size(50)
            // Ticks and unit to the right of the bar, away from the map.
            .right_y_label_area_size(80)
            .build_cartesian_2d(0.0..1.0, b0..b1)
            .map_err(plot_err)?;
        let fb = ticks(b0, b1, 6);
        bar.configure_mesh()
            .disable_x_mesh()
            .disable_x_axis()
            .disable_y_mesh()
            .y_desc(format!("value ({unit})"))
            .y_labels(6)
            .y_label_formatter(&fb)
            .label_style(("sans-serif", LABEL_PX))
            .axis_desc_style(("sans-serif", LABEL_PX))
            .draw()
            .map_err(plot_err)?;
        let n = 60;
        bar.draw_series((0..n).map(|k| {
            let a = b0 + (b1 - b0) * k as f64 / n as f64;
            let b = a + (b1 - b0) / n as f64;
            Rectangle::new([(0.0, a), (1.0, b)], diverging((a + b) / (2.0 * m)).filled())
        }))
        .map_err(plot_err)?;
        root.present().map_err(plot_err)?;
    }
    let alt = format!(
        "Text alternative: colour map of {title} over x {} to {} mm and y {} to {} mm; values from {} to {} {unit}; colour bar over the data's range, white at zero, blue negative, red positive, full colour at ±{} {unit}.",
        sig(x0),
        sig(x1),
        sig(y0),
        sig(y1),
        sig(lo),
        sig(hi),
        sig(m)
    );
    Ok(figure(&svg, title, &[], &alt))
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

    /// The header's date is the civil UTC date of the Unix time (checked against known dates).
    #[test]
    fn utc_string_is_the_civil_date() {
        assert_eq!(utc_string(0), "1970-01-01 00:00:00 UTC");
        assert_eq!(utc_string(1_700_000_000), "2023-11-14 22:13:20 UTC");
        assert_eq!(utc_string(951_782_400), "2000-02-29 00:00:00 UTC");
        assert_eq!(utc_string(-1), "1969-12-31 23:59:59 UTC");
    }

    /// With the generation time fixed (what `SOURCE_DATE_EPOCH` does in the CLI), the same
    /// content gives byte-identical pages; the time is the only thing that differs otherwise.
    #[test]
    fn reruns_are_byte_identical_with_a_fixed_time() {
        let build = |t: i64| {
            let mut r = Report::new("unused");
            r.header = Header { version: "v".into(), generated_unix_s: t, seed: 1, ..Header::default() };
            let svg = xy_plot("p", "x", "y", &[Series::line("a", vec![(0.0, 0.0), (1.0, 2.0)])]).unwrap();
            r.add("s", "S", format!("{}{svg}", table(&["a", "b"], &[vec!["x".into(), "pass".into()]])));
            r.verdict(Verdict {
                section: "s".into(),
                capability: "c".into(),
                measured: "m".into(),
                truth: "t".into(),
                result: "r".into(),
                uncertainty: "U (k = 2)".into(),
                tolerance_text: "tol".into(),
                ..Verdict::judged(Judgement::new(1.0, 1.0, 2.0, "µm", DecisionRule::Simple))
            });
            (r.html(), serde_json::to_string(&r.summary()).unwrap())
        };
        assert_eq!(build(1_700_000_000), build(1_700_000_000));
        let (a, b) = (build(1_700_000_000).0, build(1_700_000_060).0);
        assert_ne!(a, b);
        assert_eq!(a.replace("22:13:20", "22:14:20"), b, "only the time differs");
    }

    /// Text of every `<text>` element of an SVG.
    fn svg_texts(svg: &str) -> Vec<String> {
        svg.split("<text")
            .skip(1)
            .filter_map(|t| Some(t.split_once('>')?.1.split_once("</text>")?.0.trim().to_string()))
            .collect()
    }

    #[test]
    fn tick_labels_use_one_minus_sign_and_the_steps_decimals() {
        assert_eq!(tick_label(-0.5, 0.1), "\u{2212}0.5");
        assert_eq!(tick_label(-0.0001, 0.1), "0.0");
        assert_eq!(tick_label(20.0, 10.0), "20");
        assert_eq!(tick_label(1.25, 0.05), "1.25");
        assert_eq!(tick_label(-1500.0, 500.0), "\u{2212}1500");
        // Every figure kind writes negative ticks with U+2212, never a hyphen-minus.
        let neg = vec![(-3.0, -2.0), (1.0, 4.0)];
        let figs = [
            xy_plot("p", "x", "y", &[Series::points("a", neg.clone())]).unwrap(),
            xy_plot_equal("p", "x", "y", &[Series::line("a", neg)]).unwrap(),
            histogram("h", "e", &[("a", &[-2.0, -1.0, 0.5])], 10, None, &[]).unwrap(),
            heatmap("m", &[-2.0, -1.0], &[-1.0, 0.0], &[vec![-3.0, 1.0], vec![0.5, 2.0]], "µm").unwrap(),
        ];
        for f in &figs {
            let texts = svg_texts(f);
            assert!(texts.iter().any(|t| t.starts_with('\u{2212}')), "{texts:?}");
            assert!(!texts.iter().any(|t| t.starts_with('-')), "{texts:?}");
        }
    }

    #[test]
    fn histograms_take_their_own_range_and_draw_the_tolerance() {
        let tol = [Mark { label: "tolerance 0.5 µm", value: 0.5 }];
        // Errors from 0.1 to 0.3 with a 0.5 tolerance: the range starts at zero and takes in
        // the tolerance (3 % margin), so the line is on the drawing.
        let (lo, hi) = histogram_range(&[0.1, 0.2, 0.3], None, &tol);
        assert_eq!(lo, 0.0);
        assert!((hi - 0.515).abs() < 1e-12, "{hi}");
        // Large errors keep their own range; a tolerance below it widens it downwards.
        let (lo, hi) = histogram_range(&[40.0, 60.0], None, &[Mark { label: "t", value: 50.0 }]);
        assert!(lo > 39.0 && lo < 40.0 && hi > 60.0 && hi < 61.0, "{lo} {hi}");
        // A range that is given wins.
        assert_eq!(histogram_range(&[0.1], Some((-1.0, 1.0)), &tol), (-1.0, 1.0));
        let svg = histogram("h", "e (µm)", &[("a", &[0.1, 0.2, 0.3])], 10, None, &tol).unwrap();
        assert!(svg.contains("tolerance 0.5 µm (dashed line)"), "legend names the mark");
        // The dashed line is drawn as dashes: the same histogram without the mark has fewer
        // strokes (a mark outside the range is not drawn at all).
        let strokes = |svg: &str| svg.matches("<line").count() + svg.matches("<polyline").count();
        let bare = histogram("h", "e (µm)", &[("a", &[0.1, 0.2, 0.3])], 10, Some((0.0, 0.515)), &[]).unwrap();
        assert!(strokes(&svg) >= strokes(&bare) + 5, "{} vs {}", strokes(&svg), strokes(&bare));
        let outside = [Mark { label: "far", value: 9.0 }];
        let off =
            histogram("h", "e (µm)", &[("a", &[0.1, 0.2, 0.3])], 10, Some((0.0, 0.515)), &outside).unwrap();
        assert_eq!(strokes(&off), strokes(&bare));
        assert!(svg.contains("tolerance 0.5 µm at 0.5000."), "text alternative names the mark");
    }

    #[test]
    fn decisions_follow_iso_14253_1() {
        use DecisionRule::{Guarded, Simple};
        let d = |e: f64, u: f64, t: f64, r| Judgement::new(e, u, t, "µm", r).decide().0;
        assert_eq!(d(0.5, 0.2, 1.0, Simple), Outcome::Pass);
        assert_eq!(d(-0.9, 0.2, 1.0, Simple), Outcome::Pass);
        assert_eq!(d(1.1, 0.2, 1.0, Simple), Outcome::Fail);
        // U as large as the tolerance proves nothing, even with a small error.
        assert_eq!(d(0.1, 1.0, 1.0, Simple), Outcome::Inconclusive);
        assert_eq!(d(0.7, 0.2, 1.0, Guarded), Outcome::Pass);
        assert_eq!(d(0.9, 0.2, 1.0, Guarded), Outcome::Inconclusive);
        assert_eq!(d(1.1, 0.2, 1.0, Guarded), Outcome::Inconclusive);
        assert_eq!(d(1.3, 0.2, 1.0, Guarded), Outcome::Fail);
        let j = Judgement::new(0.1, 0.1, 1.0, "µm", Simple).require(false, "flags");
        assert_eq!(j.decide(), (Outcome::Fail, Some("flags".into())));
        let j = Judgement::unknown_uncertainty(0.1, 1.0, "µm", "no map u");
        assert_eq!(j.decide().0, Outcome::Inconclusive);
        assert!(Verdict::judged(j).expanded_uncertainty.is_none());
    }

    #[test]
    fn overall_is_pass_only_when_every_capability_passes() {
        let dir = tempfile::tempdir().unwrap();
        let mut r = Report::new(dir.path());
        assert_eq!(r.overall(), Overall::Incomplete);
        r.verdict(Verdict {
            section: "a".into(),
            ..Verdict::judged(Judgement::new(0.1, 0.1, 1.0, "µm", DecisionRule::Simple))
        });
        assert_eq!(r.overall(), Overall::Pass);
        r.verdict(Verdict::skipped("b", "B", "no data"));
        assert_eq!(r.overall(), Overall::Incomplete);
        let j = serde_json::to_value(&r.verdicts()[1]).unwrap();
        assert_eq!(j["verdict"], "skipped");
        assert_eq!(j["reason"], "no data");
        r.verdict(Verdict {
            section: "c".into(),
            ..Verdict::judged(Judgement::new(2.0, 0.1, 1.0, "µm", DecisionRule::Simple))
        });
        assert_eq!(r.overall(), Overall::Fail);
        let s = r.summary();
        assert_eq!(s["overall"], "fail");
        assert_eq!(s["capabilities"][0]["decision_rule"], "simple");
        assert_eq!(s["capabilities"][0]["coverage_factor"], 2.0);
        assert_eq!(s["capabilities"][0]["tolerance"], 1.0);
        assert_eq!(s["capabilities"][0]["unit"], "µm");
    }
}
