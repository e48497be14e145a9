//! Macros that write the repetitive parts of the bindings once.

/// A `#[pymethods]` block whose first items are families of getters: in `read: [fields]`,
/// each field (with its doc comment) becomes a getter returning
/// `self.read(py, &self.inner.field)`. The rest of the block follows unchanged.
macro_rules! pymethods_with_getters {
    ($ty:ty { $($read:ident: [$($(#[$doc:meta])* $field:ident),* $(,)?])* } { $($rest:tt)* }) => {
        #[pymethods]
        impl $ty {
            $($(
            $(#[$doc])*
            #[getter]
            fn $field<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
                self.$read(py, &self.inner.$field)
            }
            )*)*
            $($rest)*
        }
    };
}

/// A `#[pymethods]` block whose first items are getters that return what the wrapped
/// value says: `name: Type = { expr }` becomes a getter returning `self.inner.expr`. The
/// rest of the block follows unchanged.
macro_rules! pymethods_with_inner_getters {
    ($ty:ty { $($(#[$doc:meta])* $name:ident: $t:ty = { $($e:tt)* })* } { $($rest:tt)* }) => {
        #[pymethods]
        impl $ty {
            $(
            $(#[$doc])*
            #[getter]
            fn $name(&self) -> $t {
                self.inner.$($e)*
            }
            )*
            $($rest)*
        }
    };
}
