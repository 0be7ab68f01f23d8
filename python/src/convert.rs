//! Python values to and from RON values, so that a dict says what a RON scene says: dicts are
//! structs and maps (string keys), lists and tuples are tuples and lists, and numbers, strings and
//! booleans are themselves. `None` in a dict means "not given" (the field's default).

use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use ron::value::{Map, Number, Value};

/// The RON value of a Python value; `path` names it in errors (`scene.film.width`).
pub fn to_value(object: &Bound<'_, PyAny>, path: &str) -> PyResult<Value> {
    if object.is_instance_of::<PyBool>() {
        return Ok(Value::Bool(object.extract()?));
    }
    if object.is_instance_of::<PyInt>() {
        return match object.extract::<i64>() {
            Ok(v) => Ok(Value::Number(Number::I64(v))),
            Err(_) => object
                .extract::<u64>()
                .map(|v| Value::Number(Number::U64(v)))
                .map_err(|_| {
                    PyTypeError::new_err(format!("{path}: the integer {object} is too large"))
                }),
        };
    }
    if object.is_instance_of::<PyFloat>() {
        return Ok(Value::Number(Number::F64(object.extract::<f64>()?.into())));
    }
    if object.is_instance_of::<PyString>() {
        return Ok(Value::String(object.extract()?));
    }
    if let Ok(dict) = object.cast::<PyDict>() {
        let mut map = Map::new();
        for (key, value) in dict.iter() {
            let Ok(key) = key.extract::<String>() else {
                return Err(PyTypeError::new_err(format!(
                    "{path}: keys must be strings, found {}",
                    type_name(&key)
                )));
            };
            if value.is_none() {
                continue;
            }
            let value = to_value(&value, &format!("{path}.{key}"))?;
            map.insert(Value::String(key), value);
        }
        return Ok(Value::Map(map));
    }
    if object.is_instance_of::<PyList>() || object.is_instance_of::<PyTuple>() {
        return object
            .try_iter()?
            .enumerate()
            .map(|(i, item)| to_value(&item?, &format!("{path}[{i}]")))
            .collect::<PyResult<_>>()
            .map(Value::Seq);
    }
    // numpy arrays and scalars (float32, int64, ...) become Python lists and numbers.
    if object.hasattr("tolist")? {
        let plain = object.call_method0("tolist")?;
        if !plain.is(object) {
            return to_value(&plain, path);
        }
    }
    Err(PyTypeError::new_err(format!(
        "{path}: a scene value must be a dict, list, tuple, str, int, float or bool, found {}",
        type_name(object)
    )))
}

fn type_name(object: &Bound<'_, PyAny>) -> String {
    object
        .get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "an unknown type".into())
}

/// The Python value of a RON value (for plugin parameters shown to the user).
pub fn from_value<'py>(py: Python<'py>, value: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match value {
        Value::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
        Value::Number(n) => match n {
            Number::F32(_) | Number::F64(_) => PyFloat::new(py, n.into_f64()).into_any(),
            _ => match n.into_f64() {
                f if f.fract() == 0.0 && f.abs() < 9.0e15 => {
                    (f as i64).into_pyobject(py)?.into_any()
                }
                f => PyFloat::new(py, f).into_any(),
            },
        },
        Value::String(s) => PyString::new(py, s).into_any(),
        Value::Char(c) => PyString::new(py, &c.to_string()).into_any(),
        Value::Option(None) | Value::Unit => py.None().into_bound(py),
        Value::Option(Some(v)) => from_value(py, v)?,
        Value::Seq(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(from_value(py, item)?)?;
            }
            list.into_any()
        }
        Value::Map(map) => {
            let dict = PyDict::new(py);
            for (key, value) in map.iter() {
                dict.set_item(from_value(py, key)?, from_value(py, value)?)?;
            }
            dict.into_any()
        }
        Value::Bytes(bytes) => pyo3::types::PyBytes::new(py, bytes).into_any(),
    })
}

/// `--set`-style overrides from a mapping {path: value} or a sequence of "path=value" strings.
pub fn overrides(object: &Bound<'_, PyAny>) -> PyResult<Vec<String>> {
    if let Ok(dict) = object.cast::<PyDict>() {
        return dict
            .iter()
            .map(|(key, value)| {
                let key: String = key.extract().map_err(|_| {
                    PyTypeError::new_err("override paths must be strings such as \"film.width\"")
                })?;
                let value = to_value(&value, &key)?;
                let text = ron::to_string(&value)
                    .map_err(|e| PyTypeError::new_err(format!("{key}: {e}")))?;
                Ok(format!("{key}={text}"))
            })
            .collect();
    }
    if object.is_instance_of::<PyString>() {
        return Err(PyTypeError::new_err(
            "overrides must be a dict {path: value} or a list of \"path=value\" strings, not one string",
        ));
    }
    object
        .try_iter()
        .map_err(|_| {
            PyTypeError::new_err(
                "overrides must be a dict {path: value} or a list of \"path=value\" strings",
            )
        })?
        .map(|item| {
            item?.extract::<String>().map_err(|_| {
                PyTypeError::new_err("overrides in a list must be \"path=value\" strings")
            })
        })
        .collect()
}
