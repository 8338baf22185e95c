//! Golden tests of the reports' table layout: the thesis's rows and columns, and
//! the run page's BRE and threshold tables, pinned without their numbers (every
//! number only has to be one, with the thesis's three decimals). The inputs are
//! the committed runs in `reports/` (their `summary.json` and
//! `report_context.json`). `PROBECAL_UPDATE_GOLDEN=1` rewrites the golden file.

mod common;

use common::root;

#[test]
fn thesis_chapter_has_the_thesis_tables() {
    let chapter = probecal::report::thesis::chapter(&root().join("reports"));
    assert!(chapter.missing.is_empty(), "missing runs: {:?}", chapter.missing);
    let layout = probecal::report::thesis::layout(&chapter);
    let golden = root().join("tests/golden/thesis_layout.txt");
    if std::env::var_os("PROBECAL_UPDATE_GOLDEN").is_some() {
        std::fs::write(&golden, &layout).unwrap();
    }
    let want = std::fs::read_to_string(&golden).unwrap();
    assert_eq!(
        layout,
        want,
        "the thesis chapter's layout changed; see {}",
        golden.display()
    );
    // No cell is left unformatted or empty.
    assert!(!layout.contains('?'), "{layout}");
}

fn three_decimals(v: &serde_json::Value) -> bool {
    v.as_str()
        .is_some_and(|s| s.parse::<f64>().is_ok() && s.split('.').nth(1).is_some_and(|d| d.len() == 3))
}

#[test]
fn run_pages_have_the_thesis_columns_and_rows() {
    let mut checked = 0;
    for experiment in std::fs::read_dir(root().join("reports")).unwrap() {
        let experiment = experiment.unwrap().path();
        let Ok(datasets) = std::fs::read_dir(&experiment) else {
            continue;
        };
        for dataset in datasets {
            let file = dataset.unwrap().path().join("report_context.json");
            let Ok(text) = std::fs::read_to_string(&file) else {
                continue;
            };
            let ctx: serde_json::Value = serde_json::from_str(&text).unwrap();
            let Some(bre) = ctx["bre_table"].as_array() else {
                continue;
            };
            let rows: Vec<&str> = bre.iter().map(|r| r["parameter"].as_str().unwrap()).collect();
            assert_eq!(rows, ["Std.", "Mean", "Min", "Max"], "{}", file.display());
            for r in bre {
                let cells = r["values"].as_array().unwrap();
                assert_eq!(cells.len(), 3, "{}", file.display());
                assert!(cells.iter().all(three_decimals), "{}: {cells:?}", file.display());
            }
            let columns: Vec<&str> = ctx["threshold_columns"]
                .as_array()
                .unwrap()
                .iter()
                .map(|c| c["label"].as_str().unwrap())
                .collect();
            assert_eq!(columns.first(), Some(&"<∞"), "{}", file.display());
            let blocks = ctx["threshold_blocks"].as_array().unwrap();
            let axes: Vec<&str> = blocks.iter().map(|b| b["axis"].as_str().unwrap()).collect();
            assert_eq!(axes, ["X", "Y", "Z"], "{}", file.display());
            for b in blocks {
                let params: Vec<&str> = b["rows"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|r| r["parameter"].as_str().unwrap())
                    .collect();
                assert_eq!(params, ["Std.", "Mean", "Min", "Max"], "{}", file.display());
                for r in b["rows"].as_array().unwrap() {
                    assert_eq!(
                        r["values"].as_array().unwrap().len(),
                        columns.len(),
                        "{}",
                        file.display()
                    );
                }
            }
            checked += 1;
        }
    }
    assert!(checked >= 7, "only {checked} run pages found");
}

/// The committed reconstructions' `summary.json` and `agreement.json` read into
/// the typed results model and write back the same values: the model holds every
/// field the files carry (a field it dropped or renamed would change them).
#[test]
fn committed_reconstructions_read_into_the_results_model_whole() {
    use probecal::results::reconstruction::{Agreement, ReconstructionSummary, KIND};
    let dir = root().join("reports/reconstruction");
    let mut summaries = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let folder = entry.unwrap().path();
        let text = std::fs::read_to_string(folder.join("summary.json")).unwrap();
        let typed: ReconstructionSummary =
            serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", folder.display()));
        assert_eq!(typed.kind, KIND);
        assert_eq!(same_values(&typed, &text), Ok(()), "{}", folder.display());
        summaries += 1;
        if let Ok(text) = std::fs::read_to_string(folder.join("agreement.json")) {
            let typed: Agreement = serde_json::from_str(&text).unwrap();
            assert_eq!(same_values(&typed, &text), Ok(()), "{}", folder.display());
        }
    }
    assert!(summaries >= 5, "{summaries} reconstructions under {}", dir.display());
    // A dropped field is seen: the same text without one key does not come back whole.
    let text = std::fs::read_to_string(dir.join("SpinePhantom_NN_MEAN/summary.json")).unwrap();
    let mut value: serde_json::Value = serde_json::from_str(&text).unwrap();
    value["volume"]["extra"] = serde_json::json!(1);
    let typed: ReconstructionSummary = serde_json::from_value(value.clone()).unwrap();
    let e = same_values(&typed, &value.to_string()).unwrap_err();
    assert_eq!(e, "/volume/extra: only on one side");
}

/// Whether `typed`, written again, holds the values of `text` (numbers as the
/// same parser reads them), or the first key path that differs.
fn same_values<T: serde::Serialize>(typed: &T, text: &str) -> Result<(), String> {
    fn diff(a: &serde_json::Value, b: &serde_json::Value, at: &str) -> Result<(), String> {
        match (a, b) {
            (serde_json::Value::Object(x), serde_json::Value::Object(y)) => {
                for k in x.keys().chain(y.keys()) {
                    match (x.get(k), y.get(k)) {
                        (Some(p), Some(q)) => diff(p, q, &format!("{at}/{k}"))?,
                        _ => return Err(format!("{at}/{k}: only on one side")),
                    }
                }
                Ok(())
            }
            _ if a == b => Ok(()),
            _ => Err(format!("{at}: {a} against {b}")),
        }
    }
    let again = serde_json::to_value(typed).map_err(|e| e.to_string())?;
    let read: serde_json::Value = serde_json::from_str(text).map_err(|e| e.to_string())?;
    diff(&again, &read, "")
}

/// No committed page prints `null` where a value is absent: the LaTeX and HTML
/// pages say "—" (a JSON null that reached a template is a bug of its context).
#[test]
fn committed_pages_print_no_null() {
    fn pages(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                pages(&path, out);
            } else if path.extension().is_some_and(|e| e == "tex" || e == "html") {
                out.push(path);
            }
        }
    }
    fn nulls(text: &str) -> usize {
        ["& null", "null \\\\", "<td>null</td>"]
            .iter()
            .map(|n| text.matches(n).count())
            .sum()
    }
    let mut found = Vec::new();
    pages(&root().join("reports"), &mut found);
    assert!(found.len() > 20, "{} pages", found.len());
    let bad: Vec<String> = found
        .iter()
        .filter(|p| nulls(&std::fs::read_to_string(p).unwrap()) > 0)
        .map(|p| p.display().to_string())
        .collect();
    assert!(bad.is_empty(), "pages printing null: {bad:#?}");
    assert_eq!(nulls("a & 0.5 & null \\\\\n<td>null</td>"), 3);
}
