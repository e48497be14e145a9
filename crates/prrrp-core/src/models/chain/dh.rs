//! Denavit–Hartenberg conventions; [`super::Joint::from_dh`] turns a row into a joint.

/// Which Denavit–Hartenberg convention a table follows.
///
/// Both conventions number links 1..n and attach frame i to link i; frame 0 is the fixed
/// base (world) frame. They differ in where frame i sits on link i and which row holds
/// which constant:
///
/// - [`DhConvention::Standard`] (Denavit–Hartenberg 1955, Paul 1981, the paper's Table 1,
///   Corke's `SerialLink` default): ⁱ⁻¹Tᵢ = Rz(θᵢ)·Tz(dᵢ)·Tx(aᵢ)·Rx(αᵢ). Joint i moves
///   about/along z_{i−1}; frame i sits at the **distal** end of link i (on the axis of
///   joint i+1). Row i holds (θᵢ, dᵢ, aᵢ, αᵢ).
/// - [`DhConvention::Modified`] (Craig 1986, Khalil–Kleinfinger): ⁱ⁻¹Tᵢ =
///   Rx(αᵢ₋₁)·Tx(aᵢ₋₁)·Rz(θᵢ)·Tz(dᵢ). Joint i moves about/along zᵢ; frame i sits at the
///   **proximal** end of link i (on the axis of joint i). Row i holds (αᵢ₋₁, aᵢ₋₁, θᵢ, dᵢ)
///   as Craig's tables list them: the `alpha` and `a` fields of row i are the twist and
///   length of the *previous* link.
///
/// In both, the joint coordinate qᵢ adds to θᵢ (revolute) or to dᵢ (prismatic).
/// [`super::Joint::from_dh`] gives the general joint of a row.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DhConvention {
    /// Standard (distal) DH — the default, as in the paper's Table 1.
    #[default]
    Standard,
    /// Modified (proximal, Craig) DH.
    Modified,
}
