//! nalgebra's SVD and symmetric eigendecomposition with a bounded number of iterations.
//!
//! `SVD::new`, `pseudo_inverse` and `SymmetricEigen::new` iterate until convergence, which
//! a matrix with an infinite or NaN entry never reaches: the payload fit of a log with
//! positions near 1e80 rad (its normal matrix overflowed) spun for minutes and ignored
//! Ctrl-C. These take nalgebra's own tolerances, so a decomposition that converges is the
//! same to the bit; one that does not (or a non-finite matrix) is `None`, which each
//! caller turns into its typed error or its fallback.

use nalgebra::{DMatrix, DefaultAllocator, Dim, DimDiff, DimSub, OMatrix, SymmetricEigen, SVD, U1};

use nalgebra::allocator::Allocator;

/// Iterations allowed for an n×n problem: far above the few per value that QR sweeps
/// take (LAPACK's bidiagonal SVD allows 6n²), far below a wait anyone notices.
fn max_iterations(n: usize) -> usize {
    1000 + 30 * n * n
}

/// The thin SVD of `m` with U and Vᵀ, as `m.svd(true, true)`; `None` for a non-finite
/// matrix or no convergence.
pub(crate) fn svd(m: DMatrix<f64>) -> Option<SVD<f64, nalgebra::Dyn, nalgebra::Dyn>> {
    if !m.iter().all(|x| x.is_finite()) {
        return None;
    }
    let n = m.nrows().max(m.ncols());
    // `SVD::new`'s tolerance.
    SVD::try_new(m, true, true, f64::EPSILON * 5.0, max_iterations(n))
}

/// The eigendecomposition of the symmetric `m` (its lower triangle read), as
/// `m.symmetric_eigen()`; `None` for a non-finite matrix or no convergence.
pub(crate) fn symmetric_eigen<D>(m: OMatrix<f64, D, D>) -> Option<SymmetricEigen<f64, D>>
where
    D: Dim + DimSub<U1>,
    DefaultAllocator: Allocator<D, D> + Allocator<D> + Allocator<DimDiff<D, U1>>,
{
    if !m.iter().all(|x| x.is_finite()) {
        return None;
    }
    let n = m.nrows();
    // `SymmetricEigen::new`'s tolerance.
    SymmetricEigen::try_new(m, f64::EPSILON, max_iterations(n))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix4;

    #[test]
    fn non_finite_matrices_end_instead_of_spinning() {
        // nalgebra's unbounded loops do not return on these.
        let mut m = DMatrix::from_fn(6, 6, |r, c| 1.0 / (1 + r + c) as f64);
        m[(2, 3)] = f64::INFINITY;
        assert!(svd(m.clone()).is_none());
        m[(2, 3)] = f64::NAN;
        assert!(symmetric_eigen(m).is_none());
        let huge = DMatrix::from_element(5, 5, 1e200);
        assert!(svd(&huge * &huge).is_none());
    }

    #[test]
    fn converged_results_are_nalgebras_to_the_bit() {
        let m = DMatrix::from_fn(7, 5, |r, c| ((r * 5 + c) as f64 * 0.37).sin());
        let (ours, theirs) = (svd(m.clone()).unwrap(), m.svd(true, true));
        assert_eq!(ours.singular_values, theirs.singular_values);
        assert_eq!(ours.u, theirs.u);
        assert_eq!(ours.v_t, theirs.v_t);
        let a =
            Matrix4::from_fn(|r, c| ((r + 1) * (c + 1)) as f64 + if r == c { 3.0 } else { 0.0 });
        let (ours, theirs) = (symmetric_eigen(a).unwrap(), a.symmetric_eigen());
        assert_eq!(ours.eigenvalues, theirs.eigenvalues);
        assert_eq!(ours.eigenvectors, theirs.eigenvectors);
    }
}
