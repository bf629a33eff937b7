//! The Python package `fogline` (built by maturin, `pip install ./crates/python`): thin PyO3
//! bindings over the in-memory API of fogline's facade (`fogline_api::in_memory`, built
//! without the file-based jobs).
//!
//! This crate only converts Python arguments, releases the GIL and calls the library; the
//! work itself lives in the library crates behind the facade (`api::perturb` for the
//! corruptions). Every
//! error becomes a Python exception that names the argument at fault (`TypeError` for a
//! wrong type or dtype, `ValueError` for a wrong shape, layout or value); no panic crosses
//! the boundary (PyO3 turns one into `PanicException`, and none is expected).
//!
//! The Python-side API (docstrings, type stubs, the transform classes) is in
//! `python/fogline/`; the user guide is `docs/python.md`.

use api::perturb::deficit::DeficitRegion;
use api::perturb::rng::name_id;
use api::perturb::{
    DepthMap, FrameInput, FrameKey, FrameMut, FrameRef, FrameSource, ObjectBox, Perturbation,
    Prepared,
};
use fogline_api::in_memory as api;
use numpy::{PyArrayDyn, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString};
use rayon::prelude::*;

/// A `ValueError` naming what is at fault.
fn value_error(what: &str, msg: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("{what}: {msg}"))
}

/// The stream key of a frame named like the CLI names it: `rel` is the frame's path relative
/// to the input directory (`clip/0001.png`), its directory names the clip.
fn key_of_path(rel: &str) -> FrameKey {
    let dir = rel.rsplit_once('/').map_or("", |(d, _)| d);
    FrameKey::new(name_id(dir), 0, name_id(rel))
}

/// One frame's key from a Python `str` (a relative path, as the CLI keys it) or `int` (the
/// frame number in clip 0, camera 0).
fn key_of(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<FrameKey> {
    if let Ok(s) = obj.cast::<PyString>() {
        return Ok(key_of_path(&s.to_cow()?));
    }
    if let Ok(i) = obj.extract::<u64>() {
        return Ok(FrameKey::new(0, 0, i));
    }
    Err(PyTypeError::new_err(format!(
        "{what}: expected a str (the frame's relative path, as the CLI keys it) or a \
         non-negative int, got {}",
        type_name(obj)
    )))
}

fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map_or_else(|_| "an object".to_string(), |n| n.to_string())
}

/// `obj` as a numpy array of element type `T`, with a clear error for anything else.
fn array_of<'py, T: numpy::Element>(
    obj: &Bound<'py, PyAny>,
    what: &str,
    want: &str,
) -> PyResult<Bound<'py, PyArrayDyn<T>>> {
    if let Ok(a) = obj.cast::<PyArrayDyn<T>>() {
        return Ok(a.clone());
    }
    match obj.cast::<PyUntypedArray>() {
        Ok(a) => Err(PyTypeError::new_err(format!(
            "{what}: expected a {want} array, got dtype {} (convert with .astype(np.{want}))",
            a.dtype()
        ))),
        Err(_) => Err(PyTypeError::new_err(format!(
            "{what}: expected a numpy {want} array, got {}",
            type_name(obj)
        ))),
    }
}

/// Frames' geometry from an image array's shape: `(n, height, width, batched)`.
fn frame_shape(shape: &[usize]) -> PyResult<(usize, u32, u32, bool)> {
    let (n, h, w, c, batched) = match *shape {
        [h, w, c] => (1, h, w, c, false),
        [n, h, w, c] => (n, h, w, c, true),
        _ => {
            return Err(value_error(
                "image",
                format!(
                    "expected shape (H, W, 3) or (N, H, W, 3), got {shape:?} ({} dimensions)",
                    shape.len()
                ),
            ));
        }
    };
    if c != 3 {
        return Err(value_error(
            "image",
            format!("expected 3 channels (RGB) in the last axis, got shape {shape:?}"),
        ));
    }
    let dim = |v: usize, name: &str| {
        u32::try_from(v)
            .ok()
            .filter(|&v| v > 0)
            .ok_or_else(|| value_error("image", format!("{name} must be 1 to 2^32-1, got {v}")))
    };
    Ok((n, dim(h, "height")?, dim(w, "width")?, batched))
}

/// One box from a dict with the CLI's box fields (`class`, `x`, `y`, `width`, `height`,
/// optional `track_id`) or a tuple `(class, x, y, width, height)`.
fn box_of(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<ObjectBox> {
    if let Ok(d) = obj.cast::<PyDict>() {
        let get = |field: &str| -> PyResult<Bound<'_, PyAny>> {
            d.get_item(field)?
                .ok_or_else(|| value_error(what, format!("missing field {field:?}")))
        };
        let num = |field: &str| -> PyResult<f64> {
            get(field)?
                .extract::<f64>()
                .map_err(|_| PyTypeError::new_err(format!("{what}.{field}: expected a number")))
        };
        let track_id = match d.get_item("track_id")? {
            Some(t) if !t.is_none() => Some(t.extract::<u64>().map_err(|_| {
                PyTypeError::new_err(format!("{what}.track_id: expected a non-negative int"))
            })?),
            _ => None,
        };
        return Ok(ObjectBox {
            class: get("class")?
                .extract::<String>()
                .map_err(|_| PyTypeError::new_err(format!("{what}.class: expected a str")))?,
            track_id,
            x_px: num("x")?,
            y_px: num("y")?,
            width_px: num("width")?,
            height_px: num("height")?,
        });
    }
    if let Ok((class, x, y, w, h)) = obj.extract::<(String, f64, f64, f64, f64)>() {
        return Ok(ObjectBox {
            class,
            track_id: None,
            x_px: x,
            y_px: y,
            width_px: w,
            height_px: h,
        });
    }
    Err(PyTypeError::new_err(format!(
        "{what}: expected a dict with class, x, y, width, height (and optionally track_id) \
         or a tuple (class, x, y, width, height), got {}",
        type_name(obj)
    )))
}

fn boxes_of(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<ObjectBox>> {
    let mut out = Vec::new();
    for (i, b) in obj.try_iter()?.enumerate() {
        out.push(box_of(&b?, &format!("{what}[{i}]"))?);
    }
    Ok(out)
}

/// The items of a sequence argument that gives one value per frame of a batch.
fn per_frame<'py>(
    obj: &Bound<'py, PyAny>,
    n: usize,
    what: &str,
) -> PyResult<Vec<Bound<'py, PyAny>>> {
    if obj.is_instance_of::<PyString>() {
        return Err(PyTypeError::new_err(format!(
            "{what}: a batch of {n} frames takes a list of {n} values, one per frame"
        )));
    }
    let items: Vec<Bound<'py, PyAny>> = obj
        .try_iter()
        .map_err(|_| {
            PyTypeError::new_err(format!(
                "{what}: a batch of {n} frames takes a list of {n} values, one per frame"
            ))
        })?
        .collect::<PyResult<_>>()?;
    if items.len() != n {
        return Err(value_error(
            what,
            format!("{} values for a batch of {n} frames", items.len()),
        ));
    }
    Ok(items)
}

fn region_dict<'py>(py: Python<'py>, r: &DeficitRegion) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("class", &r.class)?;
    d.set_item("track_id", r.track_id)?;
    d.set_item("x", r.rect.x0)?;
    d.set_item("y", r.rect.y0)?;
    d.set_item("width", r.rect.x1 - r.rect.x0)?;
    d.set_item("height", r.rect.y1 - r.rect.y0)?;
    Ok(d)
}

/// One frame's work, ready to run without the GIL.
struct Job {
    key: FrameKey,
    source: FrameSource,
    boxes: Vec<ObjectBox>,
    depth: Option<DepthMap>,
}

/// Applies a prepared condition to `n` frames of `w × h` in `src`, writing `dst`.
fn run_jobs(
    prepared: &Prepared,
    jobs: &[Job],
    src: &[u8],
    dst: &mut [u8],
    (w, h): (u32, u32),
    threads: usize,
) -> Result<Vec<Vec<DeficitRegion>>, (usize, api::perturb::PerturbError)> {
    let len = w as usize * h as usize * 3;
    let one = |(i, (job, out)): (usize, (&Job, &mut [u8]))| {
        let mut out = FrameMut::new(w, h, out).map_err(|e| (i, e))?;
        match job.source {
            FrameSource::Black => {
                out.data_mut().fill(0);
                Ok(Vec::new())
            }
            FrameSource::Captured(j) => {
                let frame =
                    FrameRef::new(w, h, &src[j * len..(j + 1) * len]).map_err(|e| (i, e))?;
                let input = FrameInput {
                    frame,
                    key: job.key,
                    depth: job.depth.as_ref(),
                    boxes: &job.boxes,
                };
                prepared.apply_to(&input, &mut out).map_err(|e| (i, e))
            }
        }
    };
    let work = jobs.iter().zip(dst.chunks_exact_mut(len)).enumerate();
    if threads == 1 || jobs.len() == 1 {
        work.map(one).collect()
    } else {
        let mut all = |_: ()| -> Result<Vec<_>, _> {
            jobs.par_iter()
                .zip(dst.par_chunks_exact_mut(len))
                .enumerate()
                .map(one)
                .collect()
        };
        match threads {
            0 => all(()),
            t => match rayon::ThreadPoolBuilder::new().num_threads(t).build() {
                Ok(pool) => pool.install(|| all(())),
                Err(_) => all(()),
            },
        }
    }
}

/// Applies a condition to one frame or a batch; see `fogline.perturb` in
/// `python/fogline/__init__.py` for the user-facing documentation.
#[pyfunction]
#[pyo3(signature = (image, condition, *, seed=0, key=None, out=None, boxes=None, depth=None, threads=1, return_regions=false))]
#[allow(clippy::too_many_arguments)]
fn perturb<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    condition: &str,
    seed: u64,
    key: Option<&Bound<'py, PyAny>>,
    out: Option<&Bound<'py, PyAny>>,
    boxes: Option<&Bound<'py, PyAny>>,
    depth: Option<&Bound<'py, PyAny>>,
    threads: usize,
    return_regions: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let image = array_of::<u8>(image, "image", "uint8")?;
    let shape = image.shape().to_vec();
    let (n, h, w, batched) = frame_shape(&shape)?;
    let perturbation = Perturbation::parse(condition)
        .map_err(|e| value_error(&format!("condition {condition:?}"), e))?;
    let prepared = perturbation
        .prepare(seed)
        .map_err(|e| value_error(&format!("condition {condition:?}"), e))?;
    if perturbation.needs_depth() && depth.is_none() {
        return Err(value_error(
            &format!("condition {condition:?}"),
            "needs a depth map in metres: pass depth= (float32, H x W)",
        ));
    }
    if perturbation.uses_boxes() && boxes.is_none() {
        return Err(value_error(
            &format!("condition {condition:?}"),
            "masks objects: pass boxes= (dicts with class, x, y, width, height)",
        ));
    }

    // Keys: one per frame.
    let keys: Vec<FrameKey> = match (key, batched) {
        (None, false) => vec![FrameKey::default()],
        (None, true) => (0..n as u64).map(|i| FrameKey::new(0, 0, i)).collect(),
        (Some(k), false) => vec![key_of(k, "key")?],
        (Some(k), true) => per_frame(k, n, "key")?
            .iter()
            .enumerate()
            .map(|(i, k)| key_of(k, &format!("key[{i}]")))
            .collect::<PyResult<_>>()?,
    };
    // Boxes: one list per frame.
    let boxes: Vec<Vec<ObjectBox>> = match (boxes, batched) {
        (None, _) => vec![Vec::new(); n],
        (Some(b), false) => vec![boxes_of(b, "boxes")?],
        (Some(b), true) => per_frame(b, n, "boxes")?
            .iter()
            .enumerate()
            .map(|(i, b)| boxes_of(b, &format!("boxes[{i}]")))
            .collect::<PyResult<_>>()?,
    };
    // Depth maps: H × W, or N × H × W for a batch.
    let depths: Vec<Option<DepthMap>> = match depth {
        None => (0..n).map(|_| None).collect(),
        Some(d) => {
            let d = array_of::<f32>(d, "depth", "float32")?;
            let want: Vec<usize> = if batched {
                vec![n, h as usize, w as usize]
            } else {
                vec![h as usize, w as usize]
            };
            if d.shape() != want.as_slice() {
                return Err(value_error(
                    "depth",
                    format!(
                        "expected shape {want:?} (metres per pixel), got {:?}",
                        d.shape()
                    ),
                ));
            }
            let d = d.try_readonly().map_err(|e| value_error("depth", e))?;
            let all = d.as_slice().map_err(|_| {
                value_error(
                    "depth",
                    "the array is not C-contiguous: pass np.ascontiguousarray(depth)",
                )
            })?;
            let per = w as usize * h as usize;
            all.chunks_exact(per)
                .enumerate()
                .map(|(i, c)| {
                    DepthMap::new(w, h, c.to_vec())
                        .map(Some)
                        .map_err(|e| value_error(&format!("depth[{i}]"), e))
                })
                .collect::<PyResult<_>>()?
        }
    };
    // Temporal faults treat a batch as one clip (the first frame's clip, camera 0).
    let plan = prepared.plan_clip(keys[0].clip, 0, n);
    let jobs: Vec<Job> = keys
        .into_iter()
        .zip(plan)
        .zip(boxes)
        .zip(depths)
        .map(|(((key, source), boxes), depth)| Job {
            key,
            source,
            boxes,
            depth,
        })
        .collect();

    let src = image.try_readonly().map_err(|e| value_error("image", e))?;
    let src_bytes = src.as_slice().map_err(|_| {
        value_error(
            "image",
            "the array is not C-contiguous: pass np.ascontiguousarray(image)",
        )
    })?;
    let out = match out {
        Some(o) => {
            let o = array_of::<u8>(o, "out", "uint8")?;
            if o.shape() != shape.as_slice() {
                return Err(value_error(
                    "out",
                    format!("expected the image's shape {shape:?}, got {:?}", o.shape()),
                ));
            }
            o
        }
        None => PyArrayDyn::<u8>::zeros(py, shape.as_slice(), false),
    };
    let regions = {
        let mut dst = out.try_readwrite().map_err(|e| {
            value_error(
                "out",
                format!("cannot write it ({e}); it must be writeable and must not share memory with image"),
            )
        })?;
        let dst_bytes = dst.as_slice_mut().map_err(|_| {
            value_error(
                "out",
                "the array is not C-contiguous: pass a C-contiguous array",
            )
        })?;
        py.detach(|| run_jobs(&prepared, &jobs, src_bytes, dst_bytes, (w, h), threads))
            .map_err(|(i, e)| {
                if batched {
                    value_error(&format!("frame {i} of the batch"), e)
                } else {
                    value_error("image", e)
                }
            })?
    };
    let out = out.into_any();
    if !return_regions {
        return Ok(out);
    }
    let mut lists = Vec::with_capacity(regions.len());
    for frame in &regions {
        let list = PyList::empty(py);
        for r in frame {
            list.append(region_dict(py, r)?)?;
        }
        lists.push(list.into_any());
    }
    let regions = if batched {
        PyList::new(py, lists)?.into_any()
    } else {
        lists.swap_remove(0)
    };
    Ok((out, regions).into_pyobject(py)?.into_any())
}

/// The stream key the CLI gives a frame at relative path `rel`: `(clip, camera, frame)`.
#[pyfunction]
fn stream_key(rel: &str) -> (u64, u64, u64) {
    let k = key_of_path(rel);
    (k.clip, k.camera, k.frame)
}

/// Checks a condition (grammar and parameters) and returns its name, or a `ValueError` naming
/// what is wrong with it.
#[pyfunction]
fn condition_name(condition: &str) -> PyResult<String> {
    let p = Perturbation::parse(condition)
        .map_err(|e| value_error(&format!("condition {condition:?}"), e))?;
    p.validate()
        .map_err(|e| value_error(&format!("condition {condition:?}"), e))?;
    Ok(p.name)
}

/// Imports an object that exports the Arrow C stream interface (`__arrow_c_stream__`: a
/// pyarrow Table or RecordBatchReader, a polars DataFrame, a pandas ≥ 2.2 DataFrame with
/// pyarrow) as record batches, without copying their buffers.
fn arrow_batches(
    table: &Bound<'_, PyAny>,
) -> PyResult<(arrow_schema::SchemaRef, Vec<arrow_array::RecordBatch>)> {
    use arrow_array::RecordBatchReader;
    use arrow_array::ffi_stream::{FFI_ArrowArrayStream, RecordBatchStreamReader};
    use pyo3::types::PyCapsule;

    if !table.hasattr("__arrow_c_stream__")? {
        return Err(PyTypeError::new_err(format!(
            "table: expected a pandas or polars DataFrame or a pyarrow Table (an object with              __arrow_c_stream__), got {}",
            type_name(table)
        )));
    }
    let capsule = table.call_method0("__arrow_c_stream__")?;
    let capsule = capsule.cast::<PyCapsule>().map_err(|_| {
        PyTypeError::new_err("table: __arrow_c_stream__ did not return a PyCapsule")
    })?;
    let name = c"arrow_array_stream";
    let ptr = capsule.pointer_checked(Some(name)).map_err(|_| {
        PyTypeError::new_err(
            "table: __arrow_c_stream__ returned a capsule that is not an arrow_array_stream",
        )
    })?;
    // SAFETY: the capsule is an `arrow_array_stream` (checked above), so it points to a live
    // `FFI_ArrowArrayStream` owned by the capsule. `from_raw` moves the stream out and leaves
    // a released one behind, which the capsule's destructor then skips, as the Arrow PyCapsule
    // interface prescribes for consumers.
    #[allow(unsafe_code)]
    let reader =
        unsafe { RecordBatchStreamReader::from_raw(ptr.as_ptr().cast::<FFI_ArrowArrayStream>()) }
            .map_err(|e| value_error("table", e))?;
    let schema = reader.schema();
    let batches = reader
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| value_error("table", e))?;
    Ok((schema, batches))
}

/// Runs the envelope analysis on an Arrow-exporting table; returns `(envelope.json text,
/// envelope.md text)`, the CLI's two outputs. `params` is the JSON of `EnvelopeParams`
/// (missing fields take the defaults).
#[pyfunction]
#[pyo3(signature = (table, params, *, taxonomy="auto", allow_incomplete=false, name="<DataFrame>"))]
fn envelope_analyze(
    py: Python<'_>,
    table: &Bound<'_, PyAny>,
    params: &str,
    taxonomy: &str,
    allow_incomplete: bool,
    name: &str,
) -> PyResult<(String, String)> {
    use api::envelope::TaxonomyChoice;
    let mut p: api::envelope::EnvelopeParams =
        serde_json::from_str(params).map_err(|e| value_error("parameters", e))?;
    // As the CLI's --taxonomy: the paper's classes when the data has any of them, exactly
    // the paper's, or the labels found in the data.
    p.taxonomy = taxonomy
        .parse::<TaxonomyChoice>()
        .map_err(|e| value_error("taxonomy", e))?;
    p.validate().map_err(|e| value_error("parameters", e))?;
    let (schema, batches) = arrow_batches(table)?;
    let opts = api::envelope::ReadOptions {
        allow_incomplete,
        ..api::envelope::ReadOptions::default()
    };
    py.detach(|| {
        let t = api::envelope::read_pairs_arrow(
            name,
            &schema,
            batches.into_iter().map(Ok::<_, std::convert::Infallible>),
            &opts,
        )?;
        p.take_labels_from(&t);
        let env = api::envelope::analyze(&t, &p)?;
        let json = serde_json::to_string_pretty(&env).map_err(|e| {
            api::envelope::EnvelopeError::InvalidParam {
                name: "envelope",
                reason: e.to_string(),
            }
        })?;
        Ok((json, api::envelope::markdown::render(&env)))
    })
    .map_err(|e: api::envelope::EnvelopeError| PyValueError::new_err(e.to_string()))
}

/// The analysis parameters' defaults, as JSON (the field names `envelope_analyze` takes).
#[pyfunction]
fn envelope_defaults() -> PyResult<String> {
    serde_json::to_string(&api::envelope::EnvelopeParams::default())
        .map_err(|e| value_error("parameters", e))
}

/// Writes the synthetic pairs table of `clips` clips (the paper's scenario mix, eight
/// conditions each) as CSV to `path`.
#[pyfunction]
#[pyo3(signature = (path, clips, *, seed=0))]
fn envelope_synthetic_csv(path: std::path::PathBuf, clips: usize, seed: u64) -> PyResult<()> {
    let p = api::envelope::synthetic::SyntheticParams {
        n_clips: clips,
        seed,
    };
    let mut w = std::io::BufWriter::new(std::fs::File::create(&path)?);
    api::envelope::synthetic::write_csv(&p, &mut w)?;
    std::io::Write::flush(&mut w)?;
    Ok(())
}

/// The LLM-RCO controller, stepped once per control tick (the Python class `fogline.rco.
/// Controller` wraps it; observations and decisions cross as JSON, frames as arrays).
#[pyclass(module = "fogline._fogline")]
struct RcoController {
    /// Behind a mutex: a Python object may be touched from several threads.
    rco: std::sync::Mutex<api::rco::Rco>,
}

impl RcoController {
    fn lock(&self) -> PyResult<std::sync::MutexGuard<'_, api::rco::Rco>> {
        self.rco
            .lock()
            .map_err(|_| PyValueError::new_err("the controller failed in another thread"))
    }
}

#[pymethods]
impl RcoController {
    /// `params`: JSON of `RcoParams` (missing fields: the defaults); `backend`: `rules` or
    /// `openai` with `openai` the JSON of `OpenAiParams`.
    #[new]
    #[pyo3(signature = (params, backend="rules", openai="{}"))]
    fn new(params: &str, backend: &str, openai: &str) -> PyResult<Self> {
        let params: api::rco::RcoParams =
            serde_json::from_str(params).map_err(|e| value_error("parameters", e))?;
        let backend: Box<dyn api::rco::Backend> = match backend {
            "rules" => Box::new(api::rco::RulesBackend::default()),
            "openai" => {
                let p: api::rco::OpenAiParams =
                    serde_json::from_str(openai).map_err(|e| value_error("openai", e))?;
                Box::new(
                    api::rco::OpenAiBackend::new(p)
                        .map_err(|e| value_error("backend \"openai\"", e))?,
                )
            }
            other => {
                return Err(value_error(
                    "backend",
                    format!("expected \"rules\" or \"openai\", got {other:?}"),
                ));
            }
        };
        let rco = api::rco::Rco::new(params, backend).map_err(|e| value_error("parameters", e))?;
        Ok(Self {
            rco: std::sync::Mutex::new(rco),
        })
    }

    /// One tick: `observation` is the JSON of an `Observation` without pixels, `frames`
    /// maps camera names to `H × W × 3` uint8 arrays (copied into the observation's views).
    /// Returns the `Decision` as JSON and its one-line summary. The GIL is released while
    /// the controller (and a remote backend) works.
    fn step(
        &self,
        py: Python<'_>,
        observation: &str,
        frames: &Bound<'_, PyDict>,
    ) -> PyResult<(String, String)> {
        let mut obs: api::rco::Observation =
            serde_json::from_str(observation).map_err(|e| value_error("observation", e))?;
        for (camera, frame) in frames.iter() {
            let name: String = camera
                .extract()
                .map_err(|_| PyTypeError::new_err("frames: keys must be camera names (str)"))?;
            let what = format!("frames[{name:?}]");
            let a = array_of::<u8>(&frame, &what, "uint8")?;
            let shape = a.shape().to_vec();
            let [h, w, 3] = shape[..] else {
                return Err(value_error(
                    &what,
                    format!("expected shape (H, W, 3), got {shape:?}"),
                ));
            };
            let camera: api::types::clip::CameraId = serde_json::from_value(
                serde_json::Value::String(name.clone()),
            )
            .map_err(|_| {
                value_error(
                    &what,
                    "unknown camera: expected cross_left, front_wide, cross_right or front_tele",
                )
            })?;
            let view = obs
                .views
                .iter_mut()
                .find(|v| v.camera == camera)
                .ok_or_else(|| value_error(&what, "no view of that camera in the observation"))?;
            if (view.width as usize, view.height as usize) != (w, h) {
                return Err(value_error(
                    &what,
                    format!(
                        "the array is {w}×{h} but the view says {}×{}",
                        view.width, view.height
                    ),
                ));
            }
            let ro = a.try_readonly().map_err(|e| value_error(&what, e))?;
            let bytes = ro.as_slice().map_err(|_| {
                value_error(
                    &what,
                    "the array is not C-contiguous: pass np.ascontiguousarray(frame)",
                )
            })?;
            view.rgb = Some(std::sync::Arc::from(bytes));
        }
        if let Err(e) = obs.validate() {
            return Err(value_error("observation", e));
        }
        let mut guard = self.lock()?;
        let rco = &mut *guard;
        let decision = py.detach(|| rco.step(&obs));
        let json = serde_json::to_string(&decision).map_err(|e| value_error("decision", e))?;
        Ok((json, decision.summary()))
    }

    /// Forgets the plan, the hazards and the history (a new route).
    fn reset(&self) -> PyResult<()> {
        self.lock()?.reset();
        Ok(())
    }

    /// The backend's description (`rules`, `openai model at URL`).
    fn backend(&self) -> PyResult<String> {
        Ok(self.lock()?.backend())
    }
}

/// One `H × W × 3` uint8 frame as a borrowed byte slice with its size, or an error naming
/// `what`.
fn with_frame<R>(
    image: &Bound<'_, PyAny>,
    what: &str,
    f: impl FnOnce(&[u8], usize, usize) -> PyResult<R>,
) -> PyResult<R> {
    let a = array_of::<u8>(image, what, "uint8")?;
    let shape = a.shape().to_vec();
    let (_, h, w, batched) = frame_shape(&shape)?;
    if batched {
        return Err(value_error(
            what,
            format!("expected one frame of shape (H, W, 3), got {shape:?}"),
        ));
    }
    let ro = a.try_readonly().map_err(|e| value_error(what, e))?;
    let bytes = ro.as_slice().map_err(|_| {
        value_error(
            what,
            "the array is not C-contiguous: pass np.ascontiguousarray(frame)",
        )
    })?;
    f(bytes, w as usize, h as usize)
}

/// Blind estimates of one frame (`fogline_monitor::estimate_frame`): JSON of
/// `{noise: {sigma, sigma_se, samples, clipped_share}, condition: {gain, gain_se, fog,
/// fog_se, quantiles_used}}`. `condition` is the JSON of `ConditionParams` (`{}`: the
/// defaults). The GIL is released while the frame is measured.
#[pyfunction]
#[pyo3(signature = (image, condition="{}"))]
fn monitor_estimate(py: Python<'_>, image: &Bound<'_, PyAny>, condition: &str) -> PyResult<String> {
    let params: api::monitor::ConditionParams =
        serde_json::from_str(condition).map_err(|e| value_error("condition", e))?;
    params.validate().map_err(|e| value_error("condition", e))?;
    let e = with_frame(image, "image", |rgb, w, h| {
        py.detach(|| api::monitor::estimate_frame(rgb, w, h, &params))
            .map_err(|e| value_error("image", e))
    })?;
    serde_json::to_string(&e).map_err(|e| value_error("estimate", e))
}

/// The runtime ODD monitor of one camera stream (the Python class `fogline.monitor.Monitor`
/// wraps it; records cross as JSON, frames as arrays).
#[pyclass(module = "fogline._fogline")]
struct MonitorCore {
    /// Behind a mutex: a Python object may be touched from several threads.
    monitor: std::sync::Mutex<api::monitor::Monitor>,
}

impl MonitorCore {
    fn lock(&self) -> PyResult<std::sync::MutexGuard<'_, api::monitor::Monitor>> {
        self.monitor
            .lock()
            .map_err(|_| PyValueError::new_err("the monitor failed in another thread"))
    }
}

#[pymethods]
impl MonitorCore {
    /// `odd`: the text of an `odd.json`; `params`: JSON of `MonitorParams` (missing fields:
    /// the defaults).
    #[new]
    #[pyo3(signature = (odd, scenario, params="{}"))]
    fn new(odd: &str, scenario: &str, params: &str) -> PyResult<Self> {
        let odd = api::types::odd::OddSpec::from_json(odd).map_err(|e| value_error("odd", e))?;
        let params: api::monitor::MonitorParams =
            serde_json::from_str(params).map_err(|e| value_error("params", e))?;
        let m = api::monitor::Monitor::new(&odd, scenario, params)
            .map_err(|e| value_error("monitor", e))?;
        Ok(Self {
            monitor: std::sync::Mutex::new(m),
        })
    }

    /// Measures one `H × W × 3` uint8 frame and steps; the record as JSON.
    fn step_frame(&self, py: Python<'_>, image: &Bound<'_, PyAny>) -> PyResult<String> {
        let mut guard = self.lock()?;
        let m = &mut *guard;
        let rec = with_frame(image, "frame", |rgb, w, h| {
            py.detach(|| m.step_frame(rgb, w, h))
                .map_err(|e| value_error("frame", e))
        })?;
        serde_json::to_string(&rec).map_err(|e| value_error("record", e))
    }

    /// Steps on estimates (JSON of an `Observation`); the record as JSON.
    fn step(&self, observation: &str) -> PyResult<String> {
        let obs: api::monitor::Observation =
            serde_json::from_str(observation).map_err(|e| value_error("estimates", e))?;
        let rec = self
            .lock()?
            .step(&obs)
            .map_err(|e| value_error("estimates", e))?;
        serde_json::to_string(&rec).map_err(|e| value_error("record", e))
    }

    /// Switches to another scenario's entry, keeping the averages and the state.
    fn set_scenario(&self, scenario: &str) -> PyResult<()> {
        self.lock()?
            .set_scenario(scenario)
            .map_err(|e| value_error("scenario", e))
    }

    /// Forgets the stream.
    fn reset(&self) -> PyResult<()> {
        self.lock()?.reset();
        Ok(())
    }

    /// The decision so far (None before the first step).
    fn in_envelope(&self) -> PyResult<Option<bool>> {
        Ok(self.lock()?.in_envelope())
    }

    /// The scenario in use.
    fn scenario(&self) -> PyResult<String> {
        Ok(self.lock()?.scenario().to_string())
    }

    /// The axes watched for the scenario.
    fn watched_axes(&self) -> PyResult<Vec<String>> {
        Ok(self
            .lock()?
            .watched_axes()
            .into_iter()
            .map(str::to_string)
            .collect())
    }
}

/// The default `MonitorParams` as JSON.
#[pyfunction]
fn monitor_defaults() -> PyResult<String> {
    serde_json::to_string(&api::monitor::MonitorParams::default())
        .map_err(|e| value_error("params", e))
}

/// The bounding boxes `(x, y, width, height)` of the connected regions of a 2-D deficit mask
/// (non-zero = lost), in first-pixel order.
#[pyfunction]
fn mask_boxes(mask: &Bound<'_, PyAny>) -> PyResult<Vec<(f64, f64, f64, f64)>> {
    let what = "mask";
    let a: Bound<'_, PyArrayDyn<u8>> = match mask.cast::<PyArrayDyn<bool>>() {
        Ok(b) => b
            .call_method1("astype", ("uint8",))?
            .cast_into::<PyArrayDyn<u8>>()?,
        Err(_) => array_of::<u8>(mask, what, "uint8")?,
    };
    let shape = a.shape().to_vec();
    let [h, w] = shape[..] else {
        return Err(value_error(
            what,
            format!("expected a 2-D (H, W) mask, got shape {shape:?}"),
        ));
    };
    let ro = a.try_readonly().map_err(|e| value_error(what, e))?;
    let bytes = ro.as_slice().map_err(|_| {
        value_error(
            what,
            "the array is not C-contiguous: pass np.ascontiguousarray(mask)",
        )
    })?;
    let boxes = api::rco::PixelBox::from_mask(bytes, w, h)
        .ok_or_else(|| value_error(what, "its size does not match its shape"))?;
    Ok(boxes
        .iter()
        .map(|b| (b.x_px, b.y_px, b.width_px, b.height_px))
        .collect())
}

/// A camera from its snake-case name.
fn camera_of(name: &str, what: &str) -> PyResult<api::types::clip::CameraId> {
    serde_json::from_value(serde_json::Value::String(name.to_string())).map_err(|_| {
        value_error(
            what,
            format!("unknown camera {name:?}: expected cross_left, front_wide, cross_right or front_tele"),
        )
    })
}

fn camera_name(id: api::types::clip::CameraId) -> String {
    serde_json::to_value(id)
        .ok()
        .and_then(|v| v.as_str().map(String::from))
        .unwrap_or_default()
}

/// Generates clip `index` of a world corpus, as `fogline world generate` would write it:
/// a dict with `id`, `scenario`, `scene` (JSON text), `ego_history` (`N × 5`: t, x, y, yaw,
/// speed), `ground_truth` (`64 × 2`) and `cameras` (name → dict with `calib` (JSON text),
/// `frames` (`T × H × W × 3` uint8), `depth` (`T × H × W` float32 or `None`), `boxes` (per
/// frame, a list of dicts)).
#[pyfunction]
#[pyo3(signature = (index, *, clips, seed, mix, scenario, width, height, depth, cameras))]
#[allow(clippy::too_many_arguments)]
fn world_clip<'py>(
    py: Python<'py>,
    index: usize,
    clips: usize,
    seed: u64,
    mix: &str,
    scenario: Option<&str>,
    width: u32,
    height: u32,
    depth: bool,
    cameras: Option<Vec<String>>,
) -> PyResult<Bound<'py, PyDict>> {
    use api::world::{ScenarioMix, WorldConfig};
    if clips == 0 {
        return Err(value_error("clips", "must be at least 1"));
    }
    let mix = match (scenario, mix) {
        (Some(s), _) => ScenarioMix::only(s, clips).map_err(|e| value_error("scenario", e))?,
        (None, "paper") => ScenarioMix::paper_scaled(clips),
        (None, "uniform") => ScenarioMix::spread(clips),
        (None, other) => {
            return Err(value_error(
                "mix",
                format!("expected \"paper\" or \"uniform\", got {other:?}"),
            ));
        }
    };
    if index >= clips {
        return Err(value_error(
            "index",
            format!("{index} is not below clips={clips}"),
        ));
    }
    let config = WorldConfig {
        seed,
        width,
        height,
        depth,
        mix,
    };
    let cams = match &cameras {
        None => api::types::clip::CameraId::ALL.to_vec(),
        Some(names) => names
            .iter()
            .map(|n| camera_of(n, "cameras"))
            .collect::<PyResult<_>>()?,
    };
    let clip = py
        .detach(|| api::world::generate_clip_cameras(&config, index, &cams))
        .map_err(|e| value_error("world", e))?;

    let out = PyDict::new(py);
    out.set_item("id", &clip.id)?;
    out.set_item("scenario", &clip.scenario)?;
    out.set_item(
        "scene",
        serde_json::to_string(&clip.scene).map_err(|e| value_error("scene", e))?,
    )?;
    let hist: Vec<f64> = clip
        .ego_history
        .iter()
        .flat_map(|p| [p.t_s, p.x_m, p.y_m, p.yaw_rad, p.speed_mps])
        .collect();
    let n = clip.ego_history.len();
    out.set_item(
        "ego_history",
        numpy::PyArray1::from_vec(py, hist).reshape([n, 5])?,
    )?;
    let gt: Vec<f64> = clip.ground_truth.xy.iter().flatten().copied().collect();
    let k = clip.ground_truth.xy.len();
    out.set_item(
        "ground_truth",
        numpy::PyArray1::from_vec(py, gt).reshape([k, 2])?,
    )?;
    let cams = PyDict::new(py);
    for cam in clip.cameras {
        let c = PyDict::new(py);
        let (w, h, t) = (
            cam.calib.width as usize,
            cam.calib.height as usize,
            cam.frames.len(),
        );
        c.set_item(
            "calib",
            serde_json::to_string(&cam.calib).map_err(|e| value_error("calib", e))?,
        )?;
        let mut rgb = Vec::with_capacity(t * w * h * 3);
        let mut dep = Vec::with_capacity(if depth { t * w * h } else { 0 });
        let boxes = PyList::empty(py);
        for f in &cam.frames {
            rgb.extend_from_slice(f.image.data());
            if let Some(d) = &f.depth {
                dep.extend_from_slice(d.depth_m());
            }
            let fb = PyList::empty(py);
            for b in &f.boxes {
                let d = PyDict::new(py);
                d.set_item("class", &b.class)?;
                d.set_item("track_id", b.track_id)?;
                d.set_item("x", b.x_px)?;
                d.set_item("y", b.y_px)?;
                d.set_item("width", b.width_px)?;
                d.set_item("height", b.height_px)?;
                fb.append(d)?;
            }
            boxes.append(fb)?;
        }
        c.set_item(
            "frames",
            numpy::PyArray1::from_vec(py, rgb).reshape([t, h, w, 3])?,
        )?;
        if dep.len() == t * w * h && depth {
            c.set_item(
                "depth",
                numpy::PyArray1::from_vec(py, dep).reshape([t, h, w])?,
            )?;
        } else {
            c.set_item("depth", py.None())?;
        }
        c.set_item("boxes", boxes)?;
        cams.set_item(camera_name(cam.calib.id), c)?;
    }
    out.set_item("cameras", cams)?;
    Ok(out)
}

/// The world's scenario labels, in its order.
#[pyfunction]
fn world_scenarios() -> Vec<&'static str> {
    api::world::config::SCENARIOS.to_vec()
}

/// Runs the reference planner on frames: `cameras` maps camera names to `T × H × W × 3`
/// uint8 arrays (frames oldest first; `front_wide` needed), `calibs` optionally maps names
/// to calibration JSON (default: the standard rig at the frames' size), `ego_history` is
/// `N × 5` (t, x, y, yaw, speed). Returns the `PlannerOutput` as JSON.
#[pyfunction]
#[pyo3(signature = (cameras, ego_history, calibs=None))]
fn planner_plan(
    py: Python<'_>,
    cameras: &Bound<'_, PyDict>,
    ego_history: &Bound<'_, PyAny>,
    calibs: Option<&Bound<'_, PyDict>>,
) -> PyResult<String> {
    use api::types::clip::{CameraCalib, CameraInput, EgoPose, PlannerInput};
    let hist = array_of::<f64>(ego_history, "ego_history", "float64")?;
    let shape = hist.shape().to_vec();
    let [n, 5] = shape[..] else {
        return Err(value_error(
            "ego_history",
            format!("expected shape (N, 5): t, x, y, yaw, speed per row, got {shape:?}"),
        ));
    };
    let hist = hist
        .try_readonly()
        .map_err(|e| value_error("ego_history", e))?;
    let h = hist
        .as_slice()
        .map_err(|_| value_error("ego_history", "the array is not C-contiguous"))?;
    let poses: Vec<EgoPose> = (0..n)
        .map(|i| EgoPose {
            t_s: h[i * 5],
            x_m: h[i * 5 + 1],
            y_m: h[i * 5 + 2],
            yaw_rad: h[i * 5 + 3],
            speed_mps: h[i * 5 + 4],
        })
        .collect();
    if poses.iter().any(|p| {
        ![p.t_s, p.x_m, p.y_m, p.yaw_rad, p.speed_mps]
            .iter()
            .all(|v| v.is_finite())
    }) {
        return Err(value_error("ego_history", "every value must be finite"));
    }
    // Keep the arrays' read guards alive while the planner borrows their bytes.
    let mut guards = Vec::new();
    let mut specs = Vec::new();
    for (name, frames) in cameras.iter() {
        let name: String = name
            .extract()
            .map_err(|_| PyTypeError::new_err("cameras: keys must be camera names (str)"))?;
        let what = format!("cameras[{name:?}]");
        let id = camera_of(&name, &what)?;
        let a = array_of::<u8>(&frames, &what, "uint8")?;
        let shape = a.shape().to_vec();
        let (t, hh, ww) = match shape[..] {
            [t, hh, ww, 3] => (t, hh, ww),
            [hh, ww, 3] => (1, hh, ww),
            _ => {
                return Err(value_error(
                    &what,
                    format!("expected shape (T, H, W, 3) or (H, W, 3), got {shape:?}"),
                ));
            }
        };
        if t == 0 {
            return Err(value_error(&what, "no frame"));
        }
        let (w32, h32) = (
            u32::try_from(ww).map_err(|_| value_error(&what, "too wide"))?,
            u32::try_from(hh).map_err(|_| value_error(&what, "too tall"))?,
        );
        let calib = match calibs.and_then(|c| c.get_item(&name).ok().flatten()) {
            Some(text) => {
                let text: String = text.extract().map_err(|_| {
                    PyTypeError::new_err(format!(
                        "calibs[{name:?}]: expected calibration JSON text"
                    ))
                })?;
                let c: CameraCalib = serde_json::from_str(&text)
                    .map_err(|e| value_error(&format!("calibs[{name:?}]"), e))?;
                if (c.width, c.height) != (w32, h32) || c.id != id {
                    return Err(value_error(
                        &format!("calibs[{name:?}]"),
                        "its camera or size does not match the frames",
                    ));
                }
                c
            }
            None => CameraCalib::standard(id, w32, h32),
        };
        guards.push(a.try_readonly().map_err(|e| value_error(&what, e))?);
        specs.push((calib, t, what));
    }
    let mut inputs = Vec::new();
    for (g, (calib, t, what)) in guards.iter().zip(specs) {
        let bytes = g
            .as_slice()
            .map_err(|_| value_error(&what, "the array is not C-contiguous"))?;
        let per = bytes.len() / t;
        inputs.push(CameraInput {
            calib,
            frames: bytes.chunks_exact(per).collect(),
        });
    }
    let input = PlannerInput {
        cameras: inputs,
        ego_history: &poses,
    };
    let planner = api::planner::ReferencePlanner::new();
    let out = py
        .detach(|| planner.plan(&input))
        .map_err(|e| value_error("cameras", e))?;
    serde_json::to_string(&out).map_err(|e| value_error("output", e))
}

/// A Python exception for a failed job: `OSError` when a file could not be read or written,
/// else `ValueError`; the message is the whole error chain (it names the file and field).
fn job_error(e: &anyhow::Error) -> PyErr {
    let msg = format!("{e:#}");
    if e.chain().any(|c| c.is::<std::io::Error>()) {
        pyo3::exceptions::PyOSError::new_err(msg)
    } else {
        PyValueError::new_err(msg)
    }
}

/// A built data set as JSON (`Built`) and the summary the CLI prints.
fn built_json(b: &fogline_api::dataset::Built) -> PyResult<(String, String)> {
    let mut text = Vec::new();
    b.write_text(&mut text)
        .map_err(|e| value_error("summary", e))?;
    Ok((
        serde_json::to_string(b).map_err(|e| value_error("summary", e))?,
        String::from_utf8_lossy(&text).into_owned(),
    ))
}

/// Builds DriveLM-Deficit into `out` (`fogline dataset deficit`): `params` is the JSON of
/// `BuildParams` (missing fields: the defaults). Returns the build's summary as JSON and as
/// the CLI's text. The GIL is released while it builds.
#[pyfunction]
#[pyo3(signature = (out, params))]
fn dataset_deficit(
    py: Python<'_>,
    out: std::path::PathBuf,
    params: &str,
) -> PyResult<(String, String)> {
    let p: fogline_api::dataset::BuildParams =
        serde_json::from_str(params).map_err(|e| value_error("parameters", e))?;
    let built = py
        .detach(|| fogline_api::dataset::deficit(&p, &out))
        .map_err(|e| job_error(&e))?;
    built_json(&built)
}

/// Imports logs into a data set (`fogline dataset import`): `params` is the JSON of
/// `ImportParams`. Returns the summary as JSON and text.
#[pyfunction]
#[pyo3(signature = (logs, out, params))]
fn dataset_import(
    py: Python<'_>,
    logs: std::path::PathBuf,
    out: std::path::PathBuf,
    params: &str,
) -> PyResult<(String, String)> {
    let p: fogline_api::dataset::ImportParams =
        serde_json::from_str(params).map_err(|e| value_error("parameters", e))?;
    let built = py
        .detach(|| fogline_api::dataset::import(&p, &logs, &out))
        .map_err(|e| job_error(&e))?;
    built_json(&built)
}

/// Scores a backend on a data set (`fogline rco eval`): `split` is `train`, `val`, `test` or
/// `all`; `backend` `rules` or `openai` (with `openai` the JSON of `OpenAiParams`). Writes
/// `eval.json`, `eval.md` and `report.html` into `out` (default `data/eval`) and returns
/// the evaluation as JSON, its Markdown and the files written.
#[pyfunction]
#[pyo3(signature = (data, *, split, limit, jobs, backend, openai, out, gallery))]
#[allow(clippy::too_many_arguments)]
fn dataset_evaluate(
    py: Python<'_>,
    data: std::path::PathBuf,
    split: &str,
    limit: Option<usize>,
    jobs: usize,
    backend: &str,
    openai: &str,
    out: Option<std::path::PathBuf>,
    gallery: usize,
) -> PyResult<(String, String, Vec<std::path::PathBuf>)> {
    use fogline_api::dataset::{EvalBackend, EvalJob, EvalParams, Split};
    let split = match split {
        "all" => None,
        s => Some(Split::parse(s).ok_or_else(|| {
            value_error(
                "split",
                format!("expected train, val, test or all, got {s:?}"),
            )
        })?),
    };
    if jobs == 0 {
        return Err(value_error("jobs", "must be at least 1"));
    }
    let backend = match backend {
        "rules" => EvalBackend::Rules,
        "openai" => {
            EvalBackend::OpenAi(serde_json::from_str(openai).map_err(|e| value_error("openai", e))?)
        }
        other => {
            return Err(value_error(
                "backend",
                format!("expected \"rules\" or \"openai\", got {other:?}"),
            ));
        }
    };
    let job = EvalJob {
        data,
        out,
        backend,
        params: EvalParams { split, limit, jobs },
        gallery,
    };
    let done = py
        .detach(|| fogline_api::dataset::eval(&job))
        .map_err(|e| job_error(&e))?;
    Ok((
        serde_json::to_string(&done.eval).map_err(|e| value_error("evaluation", e))?,
        fogline_api::dataset::markdown(&done.eval),
        done.files,
    ))
}

/// The compiled half of the `fogline` package.
#[pymodule]
fn _fogline(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(perturb, m)?)?;
    m.add_function(wrap_pyfunction!(stream_key, m)?)?;
    m.add_function(wrap_pyfunction!(condition_name, m)?)?;
    m.add_function(wrap_pyfunction!(envelope_analyze, m)?)?;
    m.add_function(wrap_pyfunction!(envelope_defaults, m)?)?;
    m.add_function(wrap_pyfunction!(envelope_synthetic_csv, m)?)?;
    m.add_function(wrap_pyfunction!(mask_boxes, m)?)?;
    m.add_function(wrap_pyfunction!(world_clip, m)?)?;
    m.add_function(wrap_pyfunction!(world_scenarios, m)?)?;
    m.add_function(wrap_pyfunction!(planner_plan, m)?)?;
    m.add_class::<RcoController>()?;
    m.add_class::<MonitorCore>()?;
    m.add_function(wrap_pyfunction!(monitor_estimate, m)?)?;
    m.add_function(wrap_pyfunction!(monitor_defaults, m)?)?;
    m.add_function(wrap_pyfunction!(dataset_deficit, m)?)?;
    m.add_function(wrap_pyfunction!(dataset_import, m)?)?;
    m.add_function(wrap_pyfunction!(dataset_evaluate, m)?)?;
    Ok(())
}
