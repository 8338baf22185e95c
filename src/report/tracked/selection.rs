//! The model family's cross-validation on a tracked run's page.

/// The model family's cross-validation in a page's context (`model`, `selection`).
pub(in crate::report) fn insert_selection(ctx: &mut tera::Context, run: &crate::pipeline::tracked::TrackedRun) {
    let f3 = |v: Option<f64>| v.map(|x| format!("{x:.3}")).unwrap_or_else(|| "—".into());
    let chosen = run.selection.chosen();
    ctx.insert(
        "model",
        &format!("{:?}, {} pixels", chosen.constraints, chosen.pixel_model.name()),
    );
    let selection: Vec<serde_json::Value> = run
        .selection
        .scored
        .iter()
        .enumerate()
        .map(|(k, c)| {
            serde_json::json!({
                "constraints": format!("{:?}", c.candidate.constraints),
                "pixel_model": c.candidate.pixel_model.name(),
                "cv": f3(c.cv_pre3d_mm.map(|s| s.mean)),
                "note": c.failure.clone().unwrap_or_default(),
                "chosen": k == run.selection.chosen,
            })
        })
        .collect();
    ctx.insert("selection", &selection);
}
