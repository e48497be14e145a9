//! Macros that write the repetitive parts of the bindings once.

/// A `#[pymethods]` block whose first items are getters, written once per family (pyo3
/// allows one `#[pymethods]` block per class without the `multiple-pymethods` feature):
/// - in `read: [fields]`, each field (with its doc comment) becomes a getter returning
///   `self.read(py, &self.inner.field)`; `field()` reads `&self.inner.field()` instead;
/// - after `inner`, each `name: Type = { expr }` becomes a getter returning
///   `self.inner.expr`: what the wrapped value says, as it is.
///
/// The rest of the block follows unchanged.
macro_rules! pymethods_with_getters {
    (
        $ty:ty {
            $($read:ident: [$($(#[$doc:meta])* $field:ident $(($($arg:tt)*))?),* $(,)?])*
        }
        $(inner { $($(#[$idoc:meta])* $name:ident: $t:ty = { $($e:tt)* })* })?
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
            $($rest)*
        }
    };
}
