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
