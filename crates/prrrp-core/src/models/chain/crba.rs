//! Mass matrix by the composite-rigid-body algorithm (Walker & Orin 1982) and its
//! Cholesky factorisation, over slices (shared by both chain types).

use nalgebra::Vector3;

use super::inertia::{first_moment, inertia_times, transform_to_parent};
use super::rnea::{ChainView, LinkState};
use crate::error::{PrrrpError, Result};

impl ChainView<'_> {
    /// M(q) into the column-major n×n slice `m`, with inertial parameters `inertial`, plus
    /// the view's armature Cᵀ·diag(Ia)·C.
    /// `st` and `composite` are scratch of length n.
    #[inline]
    pub(crate) fn mass_matrix_with(
        &self,
        inertial: &[[f64; 10]],
        q: &[f64],
        st: &mut [LinkState],
        composite: &mut [[f64; 10]],
        m: &mut [f64],
    ) {
        if let Some(cf) = self.closed {
            return cf.mass_matrix(self, inertial, q, m);
        }
        let n = self.dof();
        self.placements(q, st);
        composite[..n].copy_from_slice(&inertial[..n]);
        for i in (1..n).rev() {
            let mut moved = [0.0; 10];
            transform_to_parent(&composite[i], &st[i].r, &st[i].p, &mut moved);
            for (c, x) in composite[i - 1].iter_mut().zip(moved) {
                *c += x;
            }
        }
        for i in 0..n {
            let g = &self.geom[i];
            let ic = &composite[i];
            let h = first_moment(ic);
            // Spatial force I_c·S_i about the origin of frame i.
            let mut nm = inertia_times(ic, &g.s_ang) + h.cross(&g.s_lin);
            let mut f: Vector3<f64> = g.s_lin * ic[0] - h.cross(&g.s_ang);
            m[i + n * i] = g.s_ang.dot(&nm) + g.s_lin.dot(&f);
            for j in (0..i).rev() {
                let c = &st[j + 1];
                f = c.r * f;
                nm = c.r * nm + c.p.cross(&f);
                let gj = &self.geom[j];
                let v = gj.s_ang.dot(&nm) + gj.s_lin.dot(&f);
                m[j + n * i] = v;
                m[i + n * j] = v;
            }
        }
        self.add_armature_inertia(m);
    }
}

/// In-place Cholesky M = L·Lᵀ of a column-major n×n symmetric matrix (lower triangle
/// read and overwritten with L).
///
/// # Errors
/// [`PrrrpError::NotPositiveDefinite`] if a pivot is not strictly positive and finite.
#[inline]
pub(crate) fn cholesky_in_place(a: &mut [f64], n: usize) -> Result<()> {
    for j in 0..n {
        let mut d = a[j + n * j];
        for k in 0..j {
            d -= a[j + n * k] * a[j + n * k];
        }
        if !(d > 0.0 && d.is_finite()) {
            return Err(PrrrpError::NotPositiveDefinite {
                what: "mass matrix M(q) of the chain",
            });
        }
        let d = d.sqrt();
        a[j + n * j] = d;
        for i in j + 1..n {
            let mut s = a[i + n * j];
            for k in 0..j {
                s -= a[i + n * k] * a[j + n * k];
            }
            a[i + n * j] = s / d;
        }
    }
    Ok(())
}

/// Solves L·Lᵀ·x = b in place with the factor of [`cholesky_in_place`].
#[inline]
pub(crate) fn cholesky_solve(l: &[f64], n: usize, b: &mut [f64]) {
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i + n * k] * b[k];
        }
        b[i] = s / l[i + n * i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= l[k + n * i] * b[k];
        }
        b[i] = s / l[i + n * i];
    }
}

/// M⁻¹ (column-major n×n, into `inv`) from the factor of [`cholesky_in_place`]: the n
/// solves of [`cholesky_solve`] for the unit vectors, side by side, row by row, so that
/// the columns' divisions overlap instead of each waiting on the last (each column gets
/// the same operations in the same order).
#[inline]
pub(crate) fn inverse_from_factor(l: &[f64], n: usize, inv: &mut [f64]) {
    inv.fill(0.0);
    for (j, c) in inv.chunks_exact_mut(n).enumerate() {
        c[j] = 1.0;
    }
    for i in 0..n {
        let d = l[i + n * i];
        for c in inv.chunks_exact_mut(n) {
            let mut s = c[i];
            for k in 0..i {
                s -= l[i + n * k] * c[k];
            }
            c[i] = s / d;
        }
    }
    for i in (0..n).rev() {
        let d = l[i + n * i];
        for c in inv.chunks_exact_mut(n) {
            let mut s = c[i];
            for k in i + 1..n {
                s -= l[k + n * i] * c[k];
            }
            c[i] = s / d;
        }
    }
}

/// Replaces every n-long column of `cols` (column-major) by −M⁻¹ times it, with
/// `inv` = M⁻¹ from [`inverse_from_factor`] and `tmp` scratch of length n. For many
/// right-hand sides (the 2N + B columns of the forward-dynamics derivatives) one inverse
/// and products with independent rows beat chained triangular solves per column.
#[inline]
pub(crate) fn minus_inverse_times(inv: &[f64], n: usize, cols: &mut [f64], tmp: &mut [f64]) {
    for c in cols.chunks_exact_mut(n) {
        tmp.fill(0.0);
        for (&x, mc) in c.iter().zip(inv.chunks_exact(n)) {
            if x != 0.0 {
                for (y, &mv) in tmp.iter_mut().zip(mc) {
                    *y -= mv * x;
                }
            }
        }
        c.copy_from_slice(tmp);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_solves_spd_system() {
        let n = 3;
        // Column-major SPD matrix.
        let a0 = [4.0, 2.0, 0.4, 2.0, 5.0, 1.0, 0.4, 1.0, 3.0];
        let mut l = a0;
        cholesky_in_place(&mut l, n).unwrap();
        let mut x = [1.0, -2.0, 0.5];
        let b = x;
        cholesky_solve(&l, n, &mut x);
        for i in 0..n {
            let ax: f64 = (0..n).map(|k| a0[i + n * k] * x[k]).sum();
            assert!((ax - b[i]).abs() < 1e-14);
        }
        let mut bad = [1.0, 2.0, 2.0, 1.0];
        assert!(cholesky_in_place(&mut bad, 2).is_err());
    }

    /// The inverse's solves side by side give each column the bits of its own solve,
    /// and M·M⁻¹ = I.
    #[test]
    fn inverse_columns_equal_single_solves() {
        let n = 7;
        // SPD: B·Bᵀ + n·I with B from a fixed sequence.
        let b: Vec<f64> = (0..n * n)
            .map(|k| ((k * 37 % 101) as f64 / 50.0) - 1.0)
            .collect();
        let mut a = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                a[i + n * j] = (0..n).map(|k| b[i + n * k] * b[j + n * k]).sum::<f64>()
                    + if i == j { n as f64 } else { 0.0 };
            }
        }
        let mut l = a.clone();
        cholesky_in_place(&mut l, n).unwrap();
        let mut inv = vec![0.0; n * n];
        inverse_from_factor(&l, n, &mut inv);
        for j in 0..n {
            let mut e = vec![0.0; n];
            e[j] = 1.0;
            cholesky_solve(&l, n, &mut e);
            assert_eq!(&inv[j * n..j * n + n], &e[..], "column {j}");
            for i in 0..n {
                let v: f64 = (0..n).map(|k| a[i + n * k] * inv[k + n * j]).sum();
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((v - want).abs() < 1e-13, "M·M⁻¹ ({i}, {j}): {v}");
            }
        }
    }
}
