//! Macros that write the repetitive parts of the bindings once.

/// A `#[pymethods]` block whose first items are getters, written once per family (pyo3
/// allows one `#[pymethods]` block per class without the `multiple-pymethods` feature):
/// - in `read: [fields]`, each field (with its doc comment) becomes a getter returning
///   `self.read(py, &self.inner.field)`; `field()` reads `&self.inner.field()` instead;
/// - after `inner`, each `name: Type = { expr }` becomes a getter returning
///   `self.inner.expr`: what the wrapped value says, as it is;
/// - after `arrays(this, py)`, each `fn name(a, b, ...) { body }` becomes a method taking
///   the array-like arguments `a, b, ...` (`&Bound<PyAny>`, read by `body`) and returning
///   [`crate::arrays::Out`], with `this` for `&self` and `py` for the GIL token in `body`
///   (e.g. the (q, qd, qdd) state methods of `Robot`, `SerialChain` and
///   `IdentifiedModel`).
///
/// The rest of the block follows unchanged.
macro_rules! pymethods_with_getters {
    (
        $ty:ty {
            $($read:ident: [$($(#[$doc:meta])* $field:ident $(($($arg:tt)*))?),* $(,)?])*
        }
        $(inner { $($(#[$idoc:meta])* $name:ident: $t:ty = { $($e:tt)* })* })?
        $(arrays($this:ident, $py:ident) {
            $($(#[$adoc:meta])* fn $aname:ident($($aarg:ident),+) $abody:block)*
        })?
        { $($rest:tt)* }
    ) => {
        #[pymethods]
        impl $ty {
            $($(
            $(#[$doc])*
            #[getter]
            fn $field<'py>(&self, py: Python<'py>) -> crate::arrays::Out<'py> {
                self.$read(py, &self.inner.$field$(($($arg)*))?)
            }
            )*)*
            $($(
            $(#[$idoc])*
            #[getter]
            fn $name(&self) -> $t {
                self.inner.$($e)*
            }
            )*)?
            $($(
            $(#[$adoc])*
            fn $aname<'py>(
                &self,
                $py: Python<'py>,
                $($aarg: &Bound<'py, PyAny>),+
            ) -> crate::arrays::Out<'py> {
                let $this = self;
                $abody
            }
            )*)?
            $($rest)*
        }
    };
}

/// `#[pyfunction]`s whose leading arguments are array-likes, the free-function twin of the
/// `arrays` section of [`pymethods_with_getters!`]: each `fn name(py, a, b, ...; params)
/// -> Ret { body }` (after its attributes: `#[pyfunction]`, its signature) takes the GIL
/// token `py`, the array-like arguments `a, b, ...` (`&Bound<PyAny>`, read by `body`),
/// then `params` (`name: Type`).
macro_rules! array_pyfunctions {
    ($($(#[$attr:meta])*
       fn $name:ident($py:ident, $($a:ident),+; $($p:ident: $pt:ty),* $(,)?) -> $ret:ty
       $body:block)*) => {$(
        $(#[$attr])*
        #[allow(clippy::too_many_arguments)]
        fn $name<'py>($py: Python<'py>, $($a: &Bound<'py, PyAny>,)+ $($p: $pt),*) -> $ret $body
    )*};
}
