//! `identify_cached` with one [`FitCache`] shared by every method (what `prrrp identify
//! --method all` does) gives the models of separate `identify` calls bit for bit, builds
//! the least-squares stack of W_b once per weighting, and refuses a cache filled from
//! other inputs. Data: the Panda-like 7R arm of `dyn_support` with friction on a seeded
//! Fourier excitation, τ its exact inverse dynamics plus seeded Gaussian noise.
mod dyn_support;

use std::sync::OnceLock;

use dyn_support::{exact_record, method_with_epochs, panda_like, DynFourier};
use prrrp_core::{
    identify, identify_cached, BaseOptions, BaseParameters, DynChain, DynDataset, FitCache,
    IdentifiedModel, Method, PrrrpError, METHOD_NAMES,
};

const DT: f64 = 0.01;

struct Fixture {
    chain: DynChain,
    base: BaseParameters,
    data: DynDataset,
}

/// `identify_cached` without options (what every call here passes).
fn cached(
    chain: &DynChain,
    base: &BaseParameters,
    data: &DynDataset,
    method: &Method,
    cache: &FitCache,
) -> Result<IdentifiedModel, PrrrpError> {
    identify_cached(chain, base, data, method, serde_json::json!({}), cache)
}

impl Fixture {
    /// `identify` on the fixture, without options.
    fn fresh(&self, method: &Method) -> Result<IdentifiedModel, PrrrpError> {
        identify(
            &self.chain,
            &self.base,
            &self.data,
            method,
            serde_json::json!({}),
        )
    }

    /// [`cached`] on the fixture.
    fn cached(&self, method: &Method, cache: &FitCache) -> Result<IdentifiedModel, PrrrpError> {
        cached(&self.chain, &self.base, &self.data, method, cache)
    }
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let chain = panda_like();
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let rec = exact_record(&chain, &DynFourier::seeded(11, 7, 1.0), 600, DT);
        Fixture {
            data: rec.dataset(DT, 0.05, 7),
            chain,
            base,
        }
    })
}

/// Default settings but fewer epochs for the gradient methods (seconds, not minutes; the
/// sharing does not depend on them).
fn method(name: &str) -> Method {
    method_with_epochs(name, 40)
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn assert_same(a: &IdentifiedModel, b: &IdentifiedModel, name: &str) {
    assert_eq!(bits(&a.beta), bits(&b.beta), "{name}: β");
    assert_eq!(
        a.sigma.as_deref().map(bits),
        b.sigma.as_deref().map(bits),
        "{name}: σ"
    );
    assert_eq!(bits(&a.residual_rms), bits(&b.residual_rms), "{name}: RMS");
    assert_eq!(
        a.covariance.as_deref().map(bits),
        b.covariance.as_deref().map(bits),
        "{name}: covariance"
    );
    assert_eq!(a.cond.map(f64::to_bits), b.cond.map(f64::to_bits), "{name}");
    assert_eq!(a.settings, b.settings, "{name}: settings");
    assert_eq!(
        a.standard.as_deref().map(bits),
        b.standard.as_deref().map(bits)
    );
}

#[test]
fn fit_cache_is_send_and_sync() {
    fn shared<T: Send + Sync>() {}
    shared::<FitCache>();
}

/// Every method with one cache, on two threads at once (as the Python workflow runs
/// them), equals its own `identify` call; the cache holds one stack unweighted (ls, rls,
/// adaline, hopfield) and one weighted (wls, ekf, physical).
#[test]
fn a_shared_cache_gives_every_methods_own_model() {
    let f = fixture();
    let own = |name: &str| {
        f.fresh(&method(name))
            .unwrap_or_else(|e| panic!("{name}: {e}"))
    };
    let cache = FitCache::new();
    let cached = |name: &str| {
        f.cached(&method(name), &cache)
            .unwrap_or_else(|e| panic!("{name} cached: {e}"))
    };
    let (even, odd): (Vec<_>, Vec<_>) = METHOD_NAMES
        .iter()
        .enumerate()
        .partition(|(k, _)| k % 2 == 0);
    let shared: Vec<(&str, IdentifiedModel)> = std::thread::scope(|s| {
        let a = s.spawn(|| {
            even.iter()
                .map(|(_, n)| (**n, cached(n)))
                .collect::<Vec<_>>()
        });
        let b = s.spawn(|| {
            odd.iter()
                .map(|(_, n)| (**n, cached(n)))
                .collect::<Vec<_>>()
        });
        let mut v = a.join().unwrap();
        v.extend(b.join().unwrap());
        v
    });
    assert_eq!(shared.len(), METHOD_NAMES.len());
    assert_eq!(cache.stacks(), 2);
    for (name, m) in &shared {
        assert_same(m, &own(name), name);
    }
    // A method asked again takes the stack from the cache, still the same model.
    assert_same(&cached("wls"), &own("wls"), "wls again");
    assert_eq!(cache.stacks(), 2);
    // Another rank tolerance is another stack.
    let ls = Method::Ls(prrrp_core::LsSettings {
        rank_tolerance: 1e-9,
    });
    let m = f.cached(&ls, &cache).unwrap();
    let fresh = f.fresh(&ls).unwrap();
    assert_same(&m, &fresh, "ls at 1e-9");
    assert_eq!(cache.stacks(), 3);
}

fn refused(r: Result<IdentifiedModel, PrrrpError>) {
    match r {
        Err(PrrrpError::InvalidParameter { field, .. }) => assert_eq!(field, "cache"),
        other => panic!(
            "expected the cache refused, got {:?}",
            other.map(|m| m.beta)
        ),
    }
}

/// A cache filled from one data set refuses another (one torque changed by 1 µN·m) and
/// another regressor of the same chain, for a method whose stack it holds and for one
/// whose it does not.
#[test]
fn a_cache_of_other_inputs_is_refused() {
    let f = fixture();
    let ls = method("ls");
    let cache = FitCache::new();
    f.cached(&ls, &cache).unwrap();
    let mut tau = f.data.tau().to_vec();
    tau[123] += 1e-6;
    let other = DynDataset::new(
        f.data.dof(),
        f.data.t().to_vec(),
        f.data.q().to_vec(),
        f.data.qd().to_vec(),
        f.data.qdd().to_vec(),
        tau,
    )
    .unwrap();
    for m in [&ls, &method("wls")] {
        refused(cached(&f.chain, &f.base, &other, m, &cache));
    }
    // The same chain with another Coulomb smoothing: the same joints, data and number of
    // base parameters, another regressor.
    let friction = f.chain.friction();
    let smoother = f
        .chain
        .clone()
        .with_friction(
            prrrp_core::FrictionModel {
                coulomb_smoothing: 2.0 * friction.coulomb_smoothing,
                ..friction
            },
            f.chain.friction_params().to_vec(),
        )
        .unwrap();
    let base = smoother.base_parameters(&BaseOptions::default()).unwrap();
    assert_eq!(base.count(), f.base.count());
    refused(cached(&smoother, &base, &f.data, &ls, &cache));
    // The cache still serves its own inputs.
    let again = f.cached(&ls, &cache).unwrap();
    let own = f.fresh(&ls).unwrap();
    assert_same(&again, &own, "ls");
}
