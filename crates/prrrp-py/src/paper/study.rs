//! The whole study of the paper (§5): `prrrp._prrrp.run_study_json`, wrapped by
//! `prrrp.run_study` (python/prrrp/__init__.py), which parses the JSON into a dict.

use prrrp_core::{run_study, BaseOptions, DynChain, PaperLambdaView, Robot, StudyConfig};
use pyo3::prelude::*;

use crate::arrays::UInt;
use crate::errors::ToPyResult;
use crate::interrupt::{with_progress, Callback};

/// Runs the study with `seed` on the paper robot and returns its JSON (schema_version 1).
/// `progress(stage, done, total)` is called on the calling thread while the study runs
/// (see `interrupt`); its first exception stops the study and is raised.
#[pyfunction]
#[pyo3(signature = (seed=UInt(0), progress=None))]
fn run_study_json(
    py: Python<'_>,
    seed: UInt<u64>,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let seed = seed.0;
    let config = StudyConfig {
        seed,
        ..StudyConfig::default()
    };
    let robot = Robot::paper();
    let callback = progress.as_ref().map(Callback::Staged);
    let result = with_progress(py, callback, |p| {
        run_study(&robot, &config, &|stage, done, total| {
            p.report(stage, done, total)
        })
        .and_then(|r| r.to_json())
    })?;
    result.to_py(py)
}

/// T (8 rows of b) of the paper's λ = T·β for the base parameters β of the built-in paper
/// robot (`DynChain::paper()`, default base analysis): `prrrp_core::PaperLambdaView`, the
/// one map behind the study's λ and `prrrp.paper_lambda`.
#[pyfunction]
fn paper_lambda_map(py: Python<'_>) -> PyResult<Vec<Vec<f64>>> {
    let view = (|| {
        let chain = DynChain::paper();
        let base = chain.base_parameters(&BaseOptions::default())?;
        PaperLambdaView::new(&chain.base_model(&base)?, Robot::paper().gravity)
    })()
    .to_py(py)?;
    let t = view.map();
    Ok((0..t.nrows())
        .map(|i| t.row(i).iter().copied().collect())
        .collect())
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(run_study_json, m)?)?;
    m.add_function(wrap_pyfunction!(paper_lambda_map, m)?)?;
    Ok(())
}
