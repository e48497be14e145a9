//! The paper's study on top of the library: the whole protocol of Urrea & Pascal 2017
//! (`study`) and the sensitivity of the estimates to sensor noise ([`sensitivity`]).

pub(crate) mod sensitivity;
pub(crate) mod study;

// The module's public API (also at the crate root through `prelude`).
pub use sensitivity::{sensitivity, SensitivityConfig, SensitivityReport};
pub use study::{
    run_study, EstimationData, ExcitationSummary, History, MethodEstimate, MethodValidationSummary,
    SensitivitySummary, StudyConfig, StudyProgress, StudyResult, Timings, ValidationSummary,
    METHODS,
};
