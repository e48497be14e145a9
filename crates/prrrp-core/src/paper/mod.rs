//! The paper's study on top of the library: the whole protocol of Urrea & Pascal 2017
//! (`study`), the sensitivity of the estimates to sensor noise ([`sensitivity`]) and the
//! paper's λ as a view of the paper robot's base parameters ([`PaperLambdaView`]).

pub(crate) mod lambda_view;
pub(crate) mod sensitivity;
pub(crate) mod study;

// The module's public API (also at the crate root through `prelude`).
pub use lambda_view::PaperLambdaView;
pub use sensitivity::{sensitivity, SensitivityConfig, SensitivityReport};
pub use study::{
    run_study, EstimationData, ExcitationSummary, History, MethodEstimate, MethodValidationSummary,
    SensitivitySummary, StudyConfig, StudyProgress, StudyResult, Timings, ValidationSummary,
    METHODS,
};
