//! `probecal ablate`'s outcome (`ablation.json`): the error budget of a
//! rendered rig, one row per variant of its error sources.

use serde::{Deserialize, Serialize};

use crate::pipeline::study::ablation::Ablation;

/// `ablation.json`: the ablation with the layout's version.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AblationFile {
    /// The layout's version ([`crate::results::SCHEMA_VERSION`]).
    #[serde(default = "crate::results::first_schema_version")]
    pub schema_version: u32,
    #[serde(flatten)]
    pub ablation: Ablation,
}

impl AblationFile {
    pub fn of(ablation: &Ablation) -> AblationFile {
        AblationFile {
            schema_version: crate::results::SCHEMA_VERSION,
            ablation: ablation.clone(),
        }
    }
}
