//! NumPy ↔ Rust conversions with argument-named errors (TypeError for a wrong type or dtype,
//! ValueError for a wrong shape, layout or value), and the panic guard of every binding.
use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{IntoPyArray, PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// Run `f`, turning a Rust panic into a `RuntimeError` (a binding must never abort Python or
/// surface a `PanicException`). Inputs are validated before any library call, so this is a
/// last line of defence.
pub fn guard<T>(f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(p) => {
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "unknown".into());
            Err(PyRuntimeError::new_err(format!("laparo internal error (please report): {msg}")))
        }
    }
}

/// A library error as a Python exception: I/O problems → OSError, everything else → ValueError.
pub fn lib_err(e: impl std::fmt::Display + std::fmt::Debug) -> PyErr {
    let dbg = format!("{e:?}");
    if dbg.starts_with("Io {") || dbg.contains("Io { path") {
        PyOSError::new_err(e.to_string())
    } else {
        PyValueError::new_err(e.to_string())
    }
}

/// `ValueError("<arg>: <msg>")`.
pub fn bad(arg: &str, msg: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("{arg}: {msg}"))
}

fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "?".into())
}

fn dtype_name(obj: &Bound<'_, PyAny>) -> String {
    obj.getattr("dtype").and_then(|d| d.str()).map(|s| s.to_string()).unwrap_or_else(|_| type_name(obj))
}

/// A borrowed view of a C-contiguous NumPy array: its shape and (copied only when the dtype
/// had to be widened) data.
pub struct Arr<T> {
    /// Shape of the array.
    pub shape: Vec<usize>,
    /// Row-major data.
    pub data: Vec<T>,
}

fn check_array<'py>(obj: &Bound<'py, PyAny>, arg: &str) -> PyResult<()> {
    if obj.cast::<numpy::PyUntypedArray>().is_err() {
        return Err(PyTypeError::new_err(format!("{arg}: expected a numpy.ndarray, got {}", type_name(obj))));
    }
    Ok(())
}

fn check_contig(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<()> {
    let a = obj.cast::<numpy::PyUntypedArray>().map_err(|_| bad(arg, "not an array"))?;
    if !a.is_c_contiguous() {
        return Err(bad(arg, "array is not C-contiguous (use numpy.ascontiguousarray)"));
    }
    Ok(())
}

/// Run `f` on the data of a float64 array without copying it (or on a widened copy of a
/// float32 array). TypeError for other dtypes; ValueError when not C-contiguous.
pub fn with_f64<'py, R>(
    obj: &Bound<'py, PyAny>,
    arg: &str,
    f: impl FnOnce(&[usize], &[f64]) -> PyResult<R>,
) -> PyResult<R> {
    check_array(obj, arg)?;
    check_contig(obj, arg)?;
    if let Ok(a) = obj.cast::<PyArrayDyn<f64>>() {
        let ro = a.readonly();
        let s = ro.as_slice().map_err(|e| bad(arg, e))?;
        return f(ro.shape(), s);
    }
    if let Ok(a) = obj.cast::<PyArrayDyn<f32>>() {
        let ro = a.readonly();
        let s = ro.as_slice().map_err(|e| bad(arg, e))?;
        let v: Vec<f64> = s.iter().map(|&x| x as f64).collect();
        return f(ro.shape(), &v);
    }
    Err(PyTypeError::new_err(format!("{arg}: expected dtype float64 or float32, got {}", dtype_name(obj))))
}

/// A float64 copy of a float64/float32 array.
pub fn f64_array(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Arr<f64>> {
    with_f64(obj, arg, |s, d| Ok(Arr { shape: s.to_vec(), data: d.to_vec() }))
}

/// A float32 copy of a float32/float64 array.
pub fn f32_array(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Arr<f32>> {
    check_array(obj, arg)?;
    check_contig(obj, arg)?;
    if let Ok(a) = obj.cast::<PyArrayDyn<f32>>() {
        let ro = a.readonly();
        return Ok(Arr { shape: ro.shape().to_vec(), data: ro.as_slice().map_err(|e| bad(arg, e))?.to_vec() });
    }
    let a = f64_array(obj, arg)?;
    Ok(Arr { shape: a.shape, data: a.data.iter().map(|&x| x as f32).collect() })
}

/// A uint8 image array (H, W) or (H, W, C).
pub fn u8_array(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Arr<u8>> {
    check_array(obj, arg)?;
    let Ok(a) = obj.cast::<PyArrayDyn<u8>>() else {
        return Err(PyTypeError::new_err(format!("{arg}: expected dtype uint8, got {}", dtype_name(obj))));
    };
    check_contig(obj, arg)?;
    let ro = a.readonly();
    Ok(Arr { shape: ro.shape().to_vec(), data: ro.as_slice().map_err(|e| bad(arg, e))?.to_vec() })
}

/// A boolean mask: dtype bool (or uint8, non-zero = true), shape (H, W).
pub fn bool_array(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Arr<bool>> {
    check_array(obj, arg)?;
    check_contig(obj, arg)?;
    if let Ok(a) = obj.cast::<PyArrayDyn<bool>>() {
        let ro = a.readonly();
        return Ok(Arr { shape: ro.shape().to_vec(), data: ro.as_slice().map_err(|e| bad(arg, e))?.to_vec() });
    }
    if let Ok(a) = obj.cast::<PyArrayDyn<u8>>() {
        let ro = a.readonly();
        let d = ro.as_slice().map_err(|e| bad(arg, e))?.iter().map(|&v| v != 0).collect();
        return Ok(Arr { shape: ro.shape().to_vec(), data: d });
    }
    Err(PyTypeError::new_err(format!("{arg}: expected dtype bool or uint8, got {}", dtype_name(obj))))
}

impl<T> Arr<T> {
    /// (height, width, channels) of an image-like array of 2 or 3 dimensions.
    pub fn hwc(&self, arg: &str) -> PyResult<(usize, usize, usize)> {
        match self.shape.as_slice() {
            [h, w] if *h > 0 && *w > 0 => Ok((*h, *w, 1)),
            [h, w, c] if *h > 0 && *w > 0 && *c > 0 => Ok((*h, *w, *c)),
            s => Err(bad(arg, format!("expected shape (H, W) or (H, W, C) with non-zero sizes, got {s:?}"))),
        }
    }
    /// (height, width) of a 2D array.
    pub fn hw(&self, arg: &str) -> PyResult<(usize, usize)> {
        match self.shape.as_slice() {
            [h, w] if *h > 0 && *w > 0 => Ok((*h, *w)),
            s => Err(bad(arg, format!("expected shape (H, W) with non-zero sizes, got {s:?}"))),
        }
    }
}

impl Arr<f64> {
    /// ValueError when any value is NaN or infinite.
    pub fn require_finite(&self, arg: &str) -> PyResult<()> {
        if let Some(i) = self.data.iter().position(|v| !v.is_finite()) {
            return Err(bad(arg, format!("contains a non-finite value ({}) at flat index {i}", self.data[i])));
        }
        Ok(())
    }
    /// A (rows, cols) matrix of fixed column count.
    pub fn rows(&self, arg: &str, cols: usize) -> PyResult<usize> {
        match self.shape.as_slice() {
            [n, c] if *c == cols => Ok(*n),
            s => Err(bad(arg, format!("expected shape (N, {cols}), got {s:?}"))),
        }
    }
}

/// (N, 3) finite points (mm) as vectors.
pub fn points3(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Vec<nalgebra::Vector3<f64>>> {
    let a = f64_array(obj, arg)?;
    a.rows(arg, 3)?;
    a.require_finite(arg)?;
    Ok(a.data.chunks_exact(3).map(|p| nalgebra::Vector3::new(p[0], p[1], p[2])).collect())
}

/// Row-major (N·D) values of D-vectors, for an (N, D) NumPy array.
pub fn flat<const D: usize>(v: &[nalgebra::SVector<f64, D>]) -> Vec<f64> {
    v.iter().flat_map(|x| x.iter().copied()).collect()
}

/// A tetrahedral mesh from `nodes` (N, 3) mm and `tets` (T, 4) node ids (at least one tetrahedron).
pub fn tet_mesh(nodes: &Bound<'_, PyAny>, tets: &Bound<'_, PyAny>) -> PyResult<laparo_core::mesh::TetMesh> {
    let vertices = points3(nodes, "nodes")?;
    let tets = index_rows::<4>(tets, "tets", "tets", vertices.len())?;
    if tets.is_empty() {
        return Err(bad("tets", "no tetrahedron"));
    }
    Ok(laparo_core::mesh::TetMesh { vertices, tets })
}

/// (M, K) indices into `n` items (integers, or floats with no fraction), e.g. triangle faces (K = 3)
/// or tetrahedra (K = 4); `arg` names the argument and `what` its owner in errors.
pub fn index_rows<const K: usize>(
    obj: &Bound<'_, PyAny>,
    arg: &str,
    what: &str,
    n: usize,
) -> PyResult<Vec<[usize; K]>> {
    let (shape, data) = with_f64(obj, arg, |s, d| Ok((s.to_vec(), d.to_vec()))).or_else(|_| {
        let v: Vec<[usize; K]> = obj.extract().map_err(|_| bad(arg, format!("{what}: expected (M, {K}) indices")))?;
        Ok::<_, PyErr>((vec![v.len(), K], v.iter().flatten().map(|&x| x as f64).collect()))
    })?;
    if shape.len() != 2 || shape[1] != K {
        return Err(bad(arg, format!("{what}: expected shape (M, {K}), got {shape:?}")));
    }
    data.chunks_exact(K)
        .map(|c| {
            let ok = c.iter().all(|&v| v >= 0.0 && v.fract() == 0.0 && (v as usize) < n);
            ok.then(|| std::array::from_fn(|k| c[k] as usize))
        })
        .collect::<Option<_>>()
        .ok_or_else(|| bad(arg, format!("{what}: indices must be integers in 0..{n}")))
}

/// A 1-D array (or sequence) of indices into `n` items.
pub fn indices(obj: &Bound<'_, PyAny>, arg: &str, n: usize) -> PyResult<Vec<usize>> {
    let data = match with_f64(obj, arg, |s, d| Ok((s.to_vec(), d.to_vec()))) {
        Ok((s, d)) if s.len() == 1 => d,
        Ok((s, _)) => return Err(bad(arg, format!("expected a 1-D array of indices, got shape {s:?}"))),
        Err(_) => {
            let v: Vec<usize> = obj.extract().map_err(|_| bad(arg, "expected a 1-D array of integer indices"))?;
            v.into_iter().map(|x| x as f64).collect()
        }
    };
    data.iter()
        .map(|&v| (v >= 0.0 && v.fract() == 0.0 && (v as usize) < n).then_some(v as usize))
        .collect::<Option<_>>()
        .ok_or_else(|| bad(arg, format!("indices must be integers in 0..{n}")))
}

/// A 3×3 float matrix (finite).
pub fn mat3(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<nalgebra::Matrix3<f64>> {
    let a = f64_array(obj, arg)?;
    if a.shape != [3, 3] {
        return Err(bad(arg, format!("expected shape (3, 3), got {:?}", a.shape)));
    }
    a.require_finite(arg)?;
    Ok(nalgebra::Matrix3::from_row_slice(&a.data))
}

/// A NumPy array of `shape` that takes ownership of `data` (no copy).
pub fn to_numpy<'py, T: numpy::Element>(py: Python<'py>, data: Vec<T>, shape: &[usize]) -> PyResult<Bound<'py, PyAny>> {
    let arr = ArrayD::from_shape_vec(IxDyn(shape), data).map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    Ok(arr.into_pyarray(py).into_any())
}

/// An image as (H, W) when it has one channel, else (H, W, C).
pub fn image_to_numpy<'py, T: numpy::Element>(
    py: Python<'py>,
    img: laparo_core::Image<T>,
) -> PyResult<Bound<'py, PyAny>> {
    if img.channels == 1 {
        to_numpy(py, img.data, &[img.height, img.width])
    } else {
        to_numpy(py, img.data, &[img.height, img.width, img.channels])
    }
}

/// A `serde_json::Value` as Python objects (null → None, objects → dict, arrays → list).
pub fn json_to_py<'py>(py: Python<'py>, v: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    use serde_json::Value as V;
    Ok(match v {
        V::Null => py.None().into_bound(py),
        V::Bool(b) => pyo3::types::PyBool::new(py, *b).to_owned().into_any(),
        V::Number(n) => {
            if let Some(i) = n.as_i64() {
                i.into_pyobject(py)?.into_any()
            } else if let Some(u) = n.as_u64() {
                u.into_pyobject(py)?.into_any()
            } else {
                n.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any()
            }
        }
        V::String(s) => s.into_pyobject(py)?.into_any(),
        V::Array(a) => {
            let l = PyList::empty(py);
            for x in a {
                l.append(json_to_py(py, x)?)?;
            }
            l.into_any()
        }
        V::Object(o) => {
            let d = PyDict::new(py);
            for (k, x) in o {
                d.set_item(k, json_to_py(py, x)?)?;
            }
            d.into_any()
        }
    })
}

/// Serialise `value` with serde and convert it to Python objects.
pub fn to_py<'py, S: serde::Serialize>(py: Python<'py>, value: &S) -> PyResult<Bound<'py, PyAny>> {
    let v = serde_json::to_value(value).map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    json_to_py(py, &v)
}

/// A Python object (dict/list/number) as a `serde_json::Value` via `json.dumps`.
pub fn py_to_json(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<serde_json::Value> {
    let json = obj.py().import("json")?;
    let s: String = json.call_method1("dumps", (obj,)).map_err(|e| bad(arg, e))?.extract()?;
    serde_json::from_str(&s).map_err(|e| bad(arg, e))
}

/// The rayon pool of this process: created on first use and re-created in a forked child
/// (a DataLoader worker), whose copy of the parent's pool has no threads and would hang.
static POOL: std::sync::Mutex<Option<(u32, usize, std::sync::Arc<rayon::ThreadPool>)>> = std::sync::Mutex::new(None);
/// Requested thread count (0 = rayon's default: `RAYON_NUM_THREADS`, else one per core).
static THREADS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

fn pool() -> std::sync::Arc<rayon::ThreadPool> {
    let pid = std::process::id();
    let want = THREADS.load(std::sync::atomic::Ordering::Relaxed);
    let mut g = POOL.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((p, n, pool)) = g.as_ref() {
        if *p == pid && *n == want {
            return pool.clone();
        }
    }
    if let Some((p, _, old)) = g.take() {
        if p != pid {
            // Inherited through fork(): its worker threads do not exist here; never touch it.
            std::mem::forget(old);
        }
    }
    let pool = std::sync::Arc::new(
        rayon::ThreadPoolBuilder::new()
            .num_threads(want)
            .thread_name(|i| format!("laparo-{i}"))
            .build()
            .expect("a rayon pool can be built"),
    );
    *g = Some((pid, want, pool.clone()));
    pool
}

/// Run `f` with the GIL released on this process's laparo pool.
pub fn par<R: Send, F: FnOnce() -> R + Send + pyo3::marker::Ungil>(py: Python<'_>, f: F) -> R {
    py.detach(|| pool().install(f))
}

/// Number of threads laparo uses (0 = rayon's default: `RAYON_NUM_THREADS`, else one per core).
#[pyfunction]
pub fn set_num_threads(n: usize) {
    THREADS.store(n, std::sync::atomic::Ordering::Relaxed);
}

/// Number of threads of the current laparo pool.
#[pyfunction]
pub fn get_num_threads() -> usize {
    pool().current_num_threads()
}
