//! Accessibility audit of the demo report in a real browser: writes a report with every kind of
//! element the demo uses (header, verdicts, tables, line/point plots, equal-aspect plot,
//! histogram, heat map), runs axe-core in headless Chromium through `tests/a11y/audit.js`, and
//! fails on any serious or critical violation. Screenshots (desktop and 420 px) go to
//! `target/a11y/`. Needs node, /usr/bin/chromium and `npm ci --prefix crates/report/tests/a11y`;
//! without them it prints `SKIPPED: …` and returns.
//!
//! The printed form is checked too: the report is printed to PDF by headless Chromium and read
//! back page by page with `pdftotext` (poppler-utils): every page carries the report ID and its
//! own "page x of y", and no page ends with a section heading whose content went to the next.

use std::path::PathBuf;
use std::process::Command;
use truepos_report::{self as report, Header, Report, Series, Verdict};

fn sample_report(dir: &std::path::Path) -> PathBuf {
    let mut r = Report::new(dir);
    r.header = Header {
        version: "test".into(),
        generated_unix_s: 1_700_000_000,
        command_line: "truepos demo --out x".into(),
        seed: 1,
        machine: "virtual CMM".into(),
        environment: "20 °C".into(),
    };
    r.verdict(Verdict {
        section: "s".into(),
        capability: "Cap".into(),
        measured: "m".into(),
        truth: "t".into(),
        result: "r".into(),
        uncertainty: "U = 1 µm (k = 2)".into(),
        tolerance_text: "≤ 2 µm".into(),
        ..Verdict::judged(report::Judgement::new(1.0, 1.0, 2.0, "µm", report::DecisionRule::Simple))
    });
    let circle: Vec<(f64, f64)> =
        (0..100).map(|i| (i as f64 / 15.9).cos()).zip((0..100).map(|i| (i as f64 / 15.9).sin())).collect();
    let html = [
        report::table(&["a", "b"], &[vec!["x".into(), "pass".into()], vec!["y".into(), "FAIL".into()]]),
        report::xy_plot(
            "Line",
            "x (mm)",
            "y (µm)",
            &[Series::line("l", circle.clone()), Series::points("p", circle.clone())],
        )
        .unwrap(),
        report::xy_plot_equal("Circle", "x (mm)", "y (mm)", &[Series::points("c", circle)]).unwrap(),
        report::histogram(
            "Hist",
            "e (µm)",
            &[("a", &[1.0, 2.0, 2.5]), ("b", &[0.5, 1.0])],
            10,
            Some((0.0, 3.0)),
            &[report::Mark { label: "tolerance 2.8 µm", value: 2.8 }],
        )
        .unwrap(),
        report::heatmap(
            "Heat",
            &[0.0, 1.0, 2.0],
            &[0.0, 1.0],
            &[vec![-1.0, 0.0, 1.0], vec![0.5, -0.5, 2.0]],
            "µm",
        )
        .unwrap(),
    ]
    .concat();
    r.add("s", "Section", html);
    r.write().unwrap()
}

#[test]
fn report_passes_axe_in_chromium() {
    let here = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/a11y");
    let out = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/a11y");
    std::fs::create_dir_all(&out).unwrap();
    // A real demo report when one is named (e.g. written by `truepos demo`), else a sample.
    let html = match std::env::var("TRUEPOS_REPORT_HTML") {
        Ok(p) => PathBuf::from(p),
        Err(_) => sample_report(&out.join("sample")),
    };
    if Command::new("node").arg("--version").output().is_err() {
        eprintln!("SKIPPED: node not found; the report's accessibility audit did not run");
        return;
    }
    if !std::path::Path::new("/usr/bin/chromium").exists() && std::env::var("CHROMIUM").is_err() {
        eprintln!("SKIPPED: /usr/bin/chromium not found (set CHROMIUM); the accessibility audit did not run");
        return;
    }
    if !here.join("node_modules/axe-core").exists() || !here.join("node_modules/puppeteer-core").exists() {
        eprintln!("SKIPPED: node modules missing; run `npm ci --prefix crates/report/tests/a11y`; the accessibility audit did not run");
        return;
    }
    let o = Command::new("node").arg(here.join("audit.js")).arg(&html).arg(&out).output().unwrap();
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    eprintln!("{text}");
    if o.status.code() == Some(2) {
        eprintln!("SKIPPED: the browser could not be started; the accessibility audit did not run");
        return;
    }
    assert!(o.status.success(), "serious/critical accessibility violations:\n{text}");
    assert!(out.join("report-desktop.png").exists() && out.join("report-narrow.png").exists());
}

/// Sections long enough to fill several printed pages: a verdict and a long table each.
fn long_report(dir: &std::path::Path) -> (Report, Vec<String>) {
    let mut r = Report::new(dir);
    r.header =
        Header { version: "test".into(), generated_unix_s: 1_700_000_000, seed: 1, ..Header::default() };
    let mut titles = vec![];
    for k in 0..4 {
        let id = format!("s{k}");
        r.verdict(Verdict {
            section: id.clone(),
            capability: format!("Capability {k}"),
            measured: "m".into(),
            truth: "t".into(),
            result: "r".into(),
            uncertainty: "U = 1 µm (k = 2)".into(),
            tolerance_text: "≤ 2 µm".into(),
            ..Verdict::judged(report::Judgement::new(1.0, 0.5, 2.0, "µm", report::DecisionRule::Simple))
        });
        let rows: Vec<Vec<String>> =
            (0..25 + 10 * k).map(|i| vec![format!("P{i}"), format!("{:.3}", i as f64 * 0.1 - 1.0)]).collect();
        let title = format!("Section number {k}");
        r.add(&id, &title, report::table(&["point", "error (µm)"], &rows));
        titles.push(title);
    }
    (r, titles)
}

#[test]
fn printed_report_has_its_id_and_page_numbers_on_every_page() {
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    if !std::path::Path::new(&chromium).exists() {
        eprintln!("SKIPPED: {chromium} not found (set CHROMIUM); the printed report was not checked");
        return;
    }
    if Command::new("pdftotext").arg("-v").output().is_err() {
        eprintln!(
            "SKIPPED: pdftotext not found (apt install poppler-utils); the printed report was not checked"
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (r, titles) = long_report(&dir.path().join("report"));
    let id = r.report_id();
    let html = r.write().unwrap();
    let pdf = dir.path().join("report.pdf");
    let profile = dir.path().join("profile");
    let o = Command::new(&chromium)
        .args(["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run"])
        .args(["--disable-background-networking", "--disable-component-update", "--disable-sync"])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg("--no-pdf-header-footer")
        .arg(format!("--print-to-pdf={}", pdf.display()))
        .arg(format!("file://{}", html.display()))
        .output()
        .unwrap();
    if !pdf.exists() {
        eprintln!(
            "SKIPPED: the browser did not print ({}); the printed report was not checked",
            String::from_utf8_lossy(&o.stderr).lines().last().unwrap_or("")
        );
        return;
    }
    let o = Command::new("pdftotext").arg("-layout").arg(&pdf).arg("-").output().unwrap();
    assert!(o.status.success(), "pdftotext failed: {}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8(o.stdout).unwrap();
    let pages: Vec<&str> = text.split('\u{c}').filter(|p| !p.trim().is_empty()).collect();
    let n = pages.len();
    assert!(n >= 3, "the long report should print on several pages, got {n}");
    eprintln!("printed report {id}: {n} pages, each with its ID and page number");
    for (k, page) in pages.iter().enumerate() {
        assert!(
            page.contains(&format!("truepos report {id}")),
            "page {} lacks the report ID {id}:\n{page}",
            k + 1
        );
        assert!(
            page.contains(&format!("page {} of {n}", k + 1)),
            "page {} lacks 'page {} of {n}':\n{page}",
            k + 1,
            k + 1
        );
        // The last line above the page box must not be a heading left alone at the page's end.
        let body: Vec<&str> = page
            .lines()
            .map(str::trim)
            .filter(|l| !l.is_empty() && !l.contains("truepos report TP-"))
            .collect();
        if let Some(last) = body.last() {
            assert!(
                !titles.iter().any(|t| t == last),
                "page {} ends with the orphaned heading {last:?}",
                k + 1
            );
        }
    }
}
