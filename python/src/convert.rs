//! Conversions between Python objects and the values the scene loader and
//! the simulator take: keyword arguments and dicts to TOML (the scene's own
//! syntax, which holds `nan` and `inf`, so that the loader's checks of them
//! apply), NumPy arrays to points and index lists and back.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pd_mesh::Point;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

/// A Python value as a TOML value: `None` is `Ok(None)` (the key is left
/// out, as the scene loader's default); dicts are tables, lists, tuples and
/// NumPy arrays are arrays, NumPy scalars are numbers. `what` names the
/// argument in messages.
pub(crate) fn to_toml(what: &str, obj: &Bound<'_, PyAny>) -> PyResult<Option<toml::Value>> {
    if obj.is_none() {
        return Ok(None);
    }
    if let Ok(b) = obj.cast::<PyBool>() {
        return Ok(Some(toml::Value::Boolean(b.is_true())));
    }
    if obj.is_instance_of::<PyInt>() {
        return match obj.extract::<i64>() {
            Ok(i) => Ok(Some(toml::Value::Integer(i))),
            Err(_) => Err(PyValueError::new_err(format!(
                "{what}: the integer {obj} is out of range"
            ))),
        };
    }
    if obj.is_instance_of::<PyFloat>() {
        return Ok(Some(toml::Value::Float(obj.extract::<f64>()?)));
    }
    if obj.is_instance_of::<PyString>() {
        return Ok(Some(toml::Value::String(obj.extract::<String>()?)));
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        return Ok(Some(toml::Value::Table(to_table(what, d)?)));
    }
    if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        let mut items = Vec::new();
        for (i, item) in obj.try_iter()?.enumerate() {
            let item = item?;
            match to_toml(&format!("{what}[{i}]"), &item)? {
                Some(v) => items.push(v),
                None => {
                    return Err(PyValueError::new_err(format!(
                        "{what}[{i}]: None is not a value"
                    )));
                }
            }
        }
        return Ok(Some(toml::Value::Array(items)));
    }
    // NumPy arrays and scalars: as the Python lists and numbers they hold.
    if obj.hasattr("tolist")? {
        let plain = obj.call_method0("tolist")?;
        if !plain.is(obj) {
            return to_toml(what, &plain);
        }
    }
    Err(PyValueError::new_err(format!(
        "{what}: cannot use a value of type {} (expected a number, string, bool, list or dict)",
        obj.get_type().name()?
    )))
}

/// A dict with string keys as a TOML table; keys whose value is `None`
/// are left out.
pub(crate) fn to_table(what: &str, d: &Bound<'_, PyDict>) -> PyResult<toml::Table> {
    let mut table = toml::Table::new();
    for (key, value) in d.iter() {
        let key: String = key.extract().map_err(|_| {
            PyValueError::new_err(format!("{what}: keys must be strings, got {key:?}"))
        })?;
        if let Some(v) = to_toml(&format!("{what}.{key}"), &value)? {
            table.insert(key, v);
        }
    }
    Ok(table)
}

/// `obj` as a C-contiguous NumPy array of `dtype` (no copy when it already
/// is one).
fn as_array<'py>(obj: &Bound<'py, PyAny>, dtype: &str) -> PyResult<Bound<'py, PyAny>> {
    let numpy = obj.py().import("numpy")?;
    let kwargs = PyDict::new(obj.py());
    kwargs.set_item("dtype", numpy.getattr(dtype)?)?;
    numpy.call_method("ascontiguousarray", (obj,), Some(&kwargs))
}

/// The shape of an array, as Python prints it: `(4, 2)`.
fn shape_text(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// An `(N, 3)` array of coordinates (anything NumPy converts to float64) as
/// points; `what` names the argument. With `rows`, N must be that.
pub(crate) fn points(
    what: &str,
    obj: &Bound<'_, PyAny>,
    rows: Option<usize>,
) -> PyResult<Vec<Point>> {
    let array = as_array(obj, "float64").map_err(|e| {
        PyValueError::new_err(format!("{what}: expected an (N, 3) array of numbers ({e})"))
    })?;
    let array = array.cast::<PyArrayDyn<f64>>()?;
    let shape = array.shape().to_vec();
    let wanted = rows.map_or("N".to_string(), |n| n.to_string());
    if shape.len() != 2 || shape[1] != 3 || rows.is_some_and(|n| n != shape[0]) {
        return Err(PyValueError::new_err(format!(
            "{what}: expected an ({wanted}, 3) array, got shape {}",
            shape_text(&shape)
        )));
    }
    let readonly = array.readonly();
    let values = readonly.as_slice()?;
    Ok(values
        .chunks_exact(3)
        .map(|c| Point::new(c[0], c[1], c[2]))
        .collect())
}

/// An `(M, K)` array of vertex indices (integers, not negative); `what`
/// names the argument.
pub(crate) fn indices<const K: usize>(
    what: &str,
    obj: &Bound<'_, PyAny>,
) -> PyResult<Vec<[usize; K]>> {
    let numpy = obj.py().import("numpy")?;
    let raw = numpy.call_method1("asarray", (obj,))?;
    let kind: String = raw.getattr("dtype")?.getattr("kind")?.extract()?;
    let shape: Vec<usize> = raw.getattr("shape")?.extract()?;
    let empty = shape.iter().product::<usize>() == 0;
    if !(matches!(kind.as_str(), "i" | "u") || empty) {
        return Err(PyValueError::new_err(format!(
            "{what}: expected integer vertex indices, got an array of dtype {}",
            raw.getattr("dtype")?.str()?
        )));
    }
    if empty && shape.len() <= 2 {
        return Ok(Vec::new());
    }
    if shape.len() != 2 || shape[1] != K {
        return Err(PyValueError::new_err(format!(
            "{what}: expected an (M, {K}) array of vertex indices, got shape {}",
            shape_text(&shape)
        )));
    }
    let array = as_array(&raw, "int64")?;
    let array = array.cast::<PyArrayDyn<i64>>()?;
    let readonly = array.readonly();
    let values = readonly.as_slice()?;
    values
        .chunks_exact(K)
        .enumerate()
        .map(|(row, c)| {
            let mut element = [0; K];
            for (slot, &v) in element.iter_mut().zip(c) {
                *slot = usize::try_from(v).map_err(|_| {
                    PyValueError::new_err(format!("{what}: row {row} has the negative index {v}"))
                })?;
            }
            Ok(element)
        })
        .collect()
}

/// A flat list of vertex indices (any integer sequence or 1-D array).
pub(crate) fn index_list(what: &str, obj: &Bound<'_, PyAny>) -> PyResult<Vec<usize>> {
    let numpy = obj.py().import("numpy")?;
    let raw = numpy.call_method1("asarray", (obj,))?;
    let reshaped = raw.call_method1("reshape", ((-1i64, 1i64),))?;
    Ok(indices::<1>(what, &reshaped)?
        .into_iter()
        .map(|[i]| i)
        .collect())
}

/// Points as a new `(N, 3)` float64 array (a copy the caller owns).
pub(crate) fn to_array<'py>(py: Python<'py>, points: &[Point]) -> Bound<'py, PyArray2<f64>> {
    let flat: Vec<f64> = points.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    Array2::from_shape_vec((points.len(), 3), flat)
        .expect("3 values per point")
        .into_pyarray(py)
}
