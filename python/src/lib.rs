//! `delaynav._delaynav`: the Python extension module of the `delaynav`
//! package (pyo3). The Python package (`python/delaynav/__init__.py`) wraps
//! it: what is here is the Rust side, thin calls into the library.
//!
//! - [`replay`]: `delaynav::replay::session` (what `delaynav replay LOG
//!   --json` runs) with an observer keeping every estimate as arrays.
//! - [`batch`]: many logs replayed in parallel (rayon), the GIL released.
//! - [`read_log`]: the library's log reader, every record as arrays.
//! - [`Navigator`]: the streaming [`DelayCompensatedNav`] (`f64`), its
//!   configuration a Python dict merged over the defaults like a replay's
//!   TOML configuration file (`delaynav::replay::config_file`).
//!
//! The library's errors are raised as the exceptions below with the
//! library's messages.

use delaynav::integrity::Integrity;
use delaynav::replay::config_file::{config_to_toml, merge_config};
use delaynav::replay::session::{
    ReplayObserver, ReplayOptions, ReplayReport, ReplaySetup, select_estimators,
};
use delaynav::replay::{LogReader, ReaderOptions, ReplayError, SensorEvent};
use delaynav::{
    DelayCompensatedNav, DelayCompensatedNavConfig, Estimate, Geodetic, Gps, GpsOutcome,
    GpsPosition, Imu, Mag, MagOutcome, Navigator as _,
};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use rayon::prelude::*;
use std::path::PathBuf;

create_exception!(
    _delaynav,
    DelaynavError,
    PyException,
    "Every error of the delaynav library (its message is the library's)."
);
create_exception!(
    _delaynav,
    ConfigError,
    DelaynavError,
    "An invalid configuration: names the key, the value and the bound."
);
create_exception!(
    _delaynav,
    LogError,
    DelaynavError,
    "A log that cannot be found, read or replayed."
);
create_exception!(
    _delaynav,
    SampleError,
    DelaynavError,
    "A sample the navigator refused with an error."
);

/// A replay error as its Python exception: the configuration's as
/// [`ConfigError`], the rest as [`LogError`].
fn replay_error(e: ReplayError) -> PyErr {
    match e {
        ReplayError::Config(_) | ReplayError::ConfigFile { .. } => {
            ConfigError::new_err(e.to_string())
        }
        e => LogError::new_err(e.to_string()),
    }
}

/// A Python value as TOML: bool, int, float, str, list/tuple, dict with str
/// keys; anything else is a [`ConfigError`] naming the key.
fn to_toml(value: &Bound<'_, PyAny>, key: &str) -> PyResult<toml::Value> {
    if value.is_instance_of::<PyBool>() {
        Ok(toml::Value::Boolean(value.extract()?))
    } else if value.is_instance_of::<PyInt>() {
        let i: i64 = value.extract().map_err(|_| {
            ConfigError::new_err(format!("config key `{key}`: {value} is out of range"))
        })?;
        Ok(toml::Value::Integer(i))
    } else if value.is_instance_of::<PyFloat>() {
        Ok(toml::Value::Float(value.extract()?))
    } else if value.is_instance_of::<PyString>() {
        Ok(toml::Value::String(value.extract()?))
    } else if let Ok(dict) = value.cast::<PyDict>() {
        Ok(toml::Value::Table(to_table(dict, key)?))
    } else if value.is_instance_of::<PyList>() || value.is_instance_of::<PyTuple>() {
        let items: PyResult<Vec<_>> = value.try_iter()?.map(|item| to_toml(&item?, key)).collect();
        Ok(toml::Value::Array(items?))
    } else {
        Err(ConfigError::new_err(format!(
            "config key `{key}`: {} is not a configuration value (bool, int, float, str, list or dict)",
            value.repr()?
        )))
    }
}

/// A dict as a TOML table; `prefix` is the dotted path of the dict.
fn to_table(dict: &Bound<'_, PyDict>, prefix: &str) -> PyResult<toml::Table> {
    let mut table = toml::Table::new();
    for (k, v) in dict.iter() {
        let k: String = k.extract().map_err(|_| {
            ConfigError::new_err(format!(
                "config key {} in `{prefix}` is not a str",
                k.repr().map_or_else(|_| "?".into(), |r| r.to_string())
            ))
        })?;
        let path = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        table.insert(k, to_toml(&v, &path)?);
    }
    Ok(table)
}

/// `defaults` with the dict merged over them and validated
/// (`merge_config`, as a replay's configuration file).
fn merged_config(
    defaults: DelayCompensatedNavConfig<f64>,
    config: Option<&Bound<'_, PyDict>>,
) -> PyResult<DelayCompensatedNavConfig<f64>> {
    let Some(config) = config else {
        return Ok(defaults);
    };
    let text =
        toml::to_string(&to_table(config, "")?).map_err(|e| ConfigError::new_err(e.to_string()))?;
    merge_config(defaults, &text).map_err(|e| ConfigError::new_err(e.to_string()))
}

/// A JSON value as Python objects (`json.loads`).
fn json_to_py<'py>(py: Python<'py>, value: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?
        .call_method1("loads", (value.to_string(),))
}

/// A serializable value as Python objects, through JSON.
fn serde_to_py<'py>(py: Python<'py>, value: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let json = serde_json::to_value(value).map_err(|e| DelaynavError::new_err(e.to_string()))?;
    json_to_py(py, &json)
}

/// `rows x columns` values as a 2-D array.
fn matrix<'py>(py: Python<'py>, values: Vec<f64>, columns: usize) -> Bound<'py, PyAny> {
    let rows = values.len() / columns;
    Array2::from_shape_vec((rows, columns), values)
        .expect("rows * columns values")
        .into_pyarray(py)
        .into_any()
}

/// Every estimate of one estimator, column by column.
#[derive(Default)]
struct Trace {
    t_us: Vec<u64>,
    attitude: Vec<f64>,
    euler_deg: Vec<f64>,
    aligned_euler_deg: Vec<f64>,
    position: Vec<f64>,
    velocity: Vec<f64>,
    accel_bias: Vec<f64>,
    gyro_bias: Vec<f64>,
    covariance_diagonal: Vec<f64>,
    delay_s: Vec<f64>,
    delay_std_s: Vec<f64>,
    /// Per estimate: tilt (deg), heading (deg), horizontal (m), vertical
    /// (m), velocity (m/s) and delay (s) protection levels.
    protection_levels: Vec<f64>,
    /// Per estimate, the same six quantities' validity flags.
    valid: Vec<bool>,
}

impl Trace {
    fn push(&mut self, e: &Estimate<f64>, aligned_euler_deg: Option<[f64; 3]>) {
        let q = e.attitude.quaternion();
        self.t_us.push(e.t_us);
        self.attitude.extend([q.w, q.i, q.j, q.k]);
        self.euler_deg
            .extend(e.euler_rad().iter().map(|a| a.to_degrees()));
        if let Some(aligned) = aligned_euler_deg {
            self.aligned_euler_deg.extend(aligned);
        }
        self.position.extend(e.position_ned_m.iter());
        self.velocity.extend(e.velocity_ned_m_s.iter());
        self.accel_bias.extend(e.accel_bias_m_s2.iter());
        self.gyro_bias.extend(e.gyro_bias_rad_s.iter());
        self.covariance_diagonal
            .extend(e.covariance_diagonal.iter());
        self.delay_s.push(e.delay_s.unwrap_or(f64::NAN));
        self.delay_std_s.push(e.delay_std_s.unwrap_or(f64::NAN));
    }

    fn push_integrity(&mut self, i: &Integrity<f64>) {
        let l = &i.levels;
        self.protection_levels.extend([
            l.tilt_deg,
            l.heading_deg,
            l.horizontal_m,
            l.vertical_m,
            l.velocity_m_s,
            l.delay_s,
        ]);
        self.valid.extend([
            i.tilt_valid,
            i.heading_valid,
            i.horizontal_valid,
            i.vertical_valid,
            i.velocity_valid,
            i.delay_valid,
        ]);
    }

    fn into_dict<'py>(self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("t_us", PyArray1::from_vec(py, self.t_us))?;
        d.set_item("attitude", matrix(py, self.attitude, 4))?;
        d.set_item("euler_deg", matrix(py, self.euler_deg, 3))?;
        if !self.aligned_euler_deg.is_empty() {
            d.set_item("aligned_euler_deg", matrix(py, self.aligned_euler_deg, 3))?;
        }
        d.set_item("position_ned_m", matrix(py, self.position, 3))?;
        d.set_item("velocity_ned_m_s", matrix(py, self.velocity, 3))?;
        d.set_item("accel_bias_m_s2", matrix(py, self.accel_bias, 3))?;
        d.set_item("gyro_bias_rad_s", matrix(py, self.gyro_bias, 3))?;
        d.set_item(
            "covariance_diagonal",
            matrix(py, self.covariance_diagonal, 16),
        )?;
        d.set_item("delay_s", PyArray1::from_vec(py, self.delay_s))?;
        d.set_item("delay_std_s", PyArray1::from_vec(py, self.delay_std_s))?;
        if !self.protection_levels.is_empty() {
            d.set_item(
                "protection_levels",
                matrix(py, self.protection_levels, LEVEL_NAMES.len()),
            )?;
            let rows = self.valid.len() / LEVEL_NAMES.len();
            let valid = Array2::from_shape_vec((rows, LEVEL_NAMES.len()), self.valid)
                .expect("rows * 6 flags")
                .into_pyarray(py);
            d.set_item("valid", valid)?;
            d.set_item("level_names", LEVEL_NAMES.to_vec())?;
        }
        Ok(d)
    }
}

/// Keeps every estimate of the reported passes, per estimator.
struct Collector<'a> {
    setup: &'a ReplaySetup,
    traces: Vec<(String, Trace)>,
}

/// The columns of `protection_levels` and `valid`.
const LEVEL_NAMES: [&str; 6] = [
    "tilt_deg",
    "heading_deg",
    "horizontal_m",
    "vertical_m",
    "velocity_m_s",
    "delay_s",
];

impl ReplayObserver for Collector<'_> {
    fn estimate_with_integrity(
        &mut self,
        estimator: &str,
        e: &Estimate<f64>,
        integrity: &dyn Fn() -> Integrity<f64>,
    ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        if self.traces.last().is_none_or(|(name, _)| name != estimator) {
            self.traces.push((estimator.to_string(), Trace::default()));
        }
        if let Some((_, trace)) = self.traces.last_mut() {
            trace.push(e, Some(self.setup.aligned_euler_deg(e)));
            trace.push_integrity(&integrity());
        }
        Ok(())
    }
}

/// The estimators named (each one of the library's, or `all`), in order.
fn estimators_named(
    names: &[String],
) -> PyResult<Vec<&'static delaynav::replay::session::RegisteredEstimator>> {
    let mut chosen = Vec::new();
    for name in names {
        for r in select_estimators(name).map_err(|e| PyValueError::new_err(e.to_string()))? {
            if !chosen.contains(&r) {
                chosen.push(r);
            }
        }
    }
    if chosen.is_empty() {
        return Err(PyValueError::new_err("no estimator named"));
    }
    Ok(chosen)
}

/// The replay's setup: the log's, with `config` merged over its derived
/// configuration.
fn open_setup(path: PathBuf, config: Option<&Bound<'_, PyDict>>) -> PyResult<ReplaySetup> {
    let options = ReplayOptions::new([path]);
    let setup = ReplaySetup::from_log(&options).map_err(replay_error)?;
    if config.is_none() {
        return Ok(setup);
    }
    let merged = merged_config(setup.log_config().map_err(replay_error)?, config)?;
    Ok(setup.with_config(merged))
}

/// Replays the log at `path` (a `.bin`, a `.ulg`, or a folder of CSVs)
/// through `estimators` with the defaults derived from it and `config`
/// merged over its configuration. Returns a dict: `summary` (the command
/// line's `--json`), `notes`, `config` (the resolved configuration),
/// `traces` (per estimator, every estimate as arrays) and, with
/// `reference`, the log's reference attitude.
#[pyfunction]
#[pyo3(signature = (path, config=None, estimators=vec!["proposed".to_string()], traces=true, reference=false))]
fn replay<'py>(
    py: Python<'py>,
    path: PathBuf,
    config: Option<&Bound<'py, PyDict>>,
    estimators: Vec<String>,
    traces: bool,
    reference: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let chosen = estimators_named(&estimators)?;
    let setup = open_setup(path, config)?;
    let (report, kept, reference_deg) = py
        .detach(|| {
            let scan = setup.scan()?;
            let mut collector = Collector {
                setup: &setup,
                traces: Vec::new(),
            };
            let report = if traces {
                setup.run(scan, &chosen, &mut collector)?
            } else {
                setup.run(scan, &chosen, &mut ())?
            };
            let reference_deg = if reference {
                setup.reference_attitude_deg()?
            } else {
                None
            };
            Ok::<_, ReplayError>((report, collector.traces, reference_deg))
        })
        .map_err(replay_error)?;
    let out = PyDict::new(py);
    out.set_item("summary", json_to_py(py, &report.to_json())?)?;
    let notes: Vec<String> = report.setup.notes.iter().map(|n| n.to_string()).collect();
    out.set_item("notes", notes)?;
    out.set_item("config", serde_to_py(py, &report.setup.nav)?)?;
    out.set_item("log_line", report.setup.log_line(&report.scan))?;
    out.set_item("table", report.to_string())?;
    let by_estimator = PyDict::new(py);
    for (name, trace) in kept {
        by_estimator.set_item(name, trace.into_dict(py)?)?;
    }
    out.set_item("traces", by_estimator)?;
    if let Some(rows) = reference_deg {
        out.set_item("reference", matrix(py, rows.concat(), 4))?;
    }
    Ok(out)
}

/// One log of a batch: its summary, or its error's message.
fn replay_summary(
    path: &PathBuf,
    estimators: &[&'static delaynav::replay::session::RegisteredEstimator],
) -> Result<ReplayReport, String> {
    let setup = ReplaySetup::from_log(&ReplayOptions::new([path])).map_err(|e| e.to_string())?;
    let scan = setup.scan().map_err(|e| e.to_string())?;
    setup
        .run(scan, estimators, &mut ())
        .map_err(|e| e.to_string())
}

/// A row of [`batch`]: the summary, or the error's message.
type BatchRow<'py> = (Option<Bound<'py, PyAny>>, Option<String>);

/// Replays every log of `paths` with its defaults, `workers` at a time
/// (rayon threads, the GIL released; `None`: every core). Returns, per
/// path and in order, `(summary, None)` or `(None, error message)`: a log
/// that fails is a row, never a stop.
#[pyfunction]
#[pyo3(signature = (paths, workers=None, estimators=vec!["proposed".to_string()]))]
fn batch<'py>(
    py: Python<'py>,
    paths: Vec<PathBuf>,
    workers: Option<usize>,
    estimators: Vec<String>,
) -> PyResult<Vec<BatchRow<'py>>> {
    let chosen = estimators_named(&estimators)?;
    if workers == Some(0) {
        return Err(PyValueError::new_err("workers must be at least 1"));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(workers.unwrap_or(0))
        .build()
        .map_err(|e| DelaynavError::new_err(e.to_string()))?;
    let outcomes: Vec<Result<serde_json::Value, String>> = py.detach(|| {
        pool.install(|| {
            paths
                .par_iter()
                .map(|p| {
                    std::panic::catch_unwind(|| replay_summary(p, &chosen))
                        .unwrap_or_else(|_| {
                            Err("the replay panicked (a bug: please report it)".into())
                        })
                        .map(|r| r.to_json())
                })
                .collect()
        })
    });
    outcomes
        .into_iter()
        .map(|o| match o {
            Ok(json) => Ok((Some(json_to_py(py, &json)?), None)),
            Err(e) => Ok((None, Some(e))),
        })
        .collect()
}

/// Reads every record of the log at `path` with the library's reader (the
/// replay's, IMU instance `imu_instance`): a dict of `imu`, `gps`, `mag`
/// (dicts of arrays) and `order` (the records in the reader's order: 0
/// IMU, 1 GPS, 2 magnetometer; the k-th of a kind is row k of its arrays).
#[pyfunction]
#[pyo3(signature = (path, imu_instance=0))]
fn read_log<'py>(py: Python<'py>, path: PathBuf, imu_instance: u8) -> PyResult<Bound<'py, PyDict>> {
    let options = ReaderOptions {
        imu_instance,
        ..ReaderOptions::default()
    };
    let events: Vec<SensorEvent<f64>> = py
        .detach(|| LogReader::<f64>::open_paths(&[path], None, &options).map(|r| r.collect()))
        .map_err(replay_error)?;
    let (mut order, mut imu_t, mut gyro, mut accel) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut gps_t, mut geodetic, mut ned, mut gps_vel, mut acc) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut mag_t, mut field) = (Vec::new(), Vec::new());
    for e in &events {
        match e {
            SensorEvent::Imu(s) => {
                order.push(0u8);
                imu_t.push(s.t_us);
                gyro.extend(s.gyro_rad_s.iter());
                accel.extend(s.accel_m_s2.iter());
            }
            SensorEvent::Gps(g) => {
                order.push(1);
                gps_t.push(g.t_us);
                match g.position {
                    GpsPosition::Geodetic(p) => {
                        geodetic.extend([p.lat_deg, p.lon_deg, p.alt_m]);
                        ned.extend([f64::NAN; 3]);
                    }
                    GpsPosition::Ned(p) => {
                        geodetic.extend([f64::NAN; 3]);
                        ned.extend(p.iter());
                    }
                }
                gps_vel.extend(g.velocity_ned_m_s.iter());
                acc.extend(
                    [
                        g.horizontal_accuracy_m,
                        g.vertical_accuracy_m,
                        g.speed_accuracy_m_s,
                    ]
                    .map(|a| a.unwrap_or(f64::NAN)),
                );
            }
            SensorEvent::Mag(m) => {
                order.push(2);
                mag_t.push(m.t_us);
                field.extend(m.field_body.iter());
            }
        }
    }
    let imu = PyDict::new(py);
    imu.set_item("t_us", PyArray1::from_vec(py, imu_t))?;
    imu.set_item("gyro_rad_s", matrix(py, gyro, 3))?;
    imu.set_item("accel_m_s2", matrix(py, accel, 3))?;
    let gps = PyDict::new(py);
    gps.set_item("t_us", PyArray1::from_vec(py, gps_t))?;
    gps.set_item("geodetic", matrix(py, geodetic, 3))?;
    gps.set_item("position_ned_m", matrix(py, ned, 3))?;
    gps.set_item("velocity_ned_m_s", matrix(py, gps_vel, 3))?;
    gps.set_item("accuracy", matrix(py, acc, 3))?;
    let mag = PyDict::new(py);
    mag.set_item("t_us", PyArray1::from_vec(py, mag_t))?;
    mag.set_item("field_body", matrix(py, field, 3))?;
    let out = PyDict::new(py);
    out.set_item("imu", imu)?;
    out.set_item("gps", gps)?;
    out.set_item("mag", mag)?;
    out.set_item("order", PyArray1::from_vec(py, order))?;
    Ok(out)
}

/// An estimate as a dict of arrays and numbers.
fn estimate_dict<'py>(py: Python<'py>, e: &Estimate<f64>) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let q = e.attitude.quaternion();
    d.set_item("t_us", e.t_us)?;
    d.set_item("attitude", PyArray1::from_vec(py, vec![q.w, q.i, q.j, q.k]))?;
    d.set_item(
        "euler_deg",
        PyArray1::from_iter(py, e.euler_rad().iter().map(|a| a.to_degrees())),
    )?;
    let v3 = |v: &delaynav::nalgebra::Vector3<f64>| PyArray1::from_slice(py, v.as_slice());
    d.set_item("position_ned_m", v3(&e.position_ned_m))?;
    d.set_item("velocity_ned_m_s", v3(&e.velocity_ned_m_s))?;
    d.set_item("accel_bias_m_s2", v3(&e.accel_bias_m_s2))?;
    d.set_item("gyro_bias_rad_s", v3(&e.gyro_bias_rad_s))?;
    d.set_item(
        "covariance_diagonal",
        PyArray1::from_slice(py, e.covariance_diagonal.as_slice()),
    )?;
    d.set_item("delay_s", e.delay_s)?;
    d.set_item("delay_std_s", e.delay_std_s)?;
    Ok(d)
}

/// The delay-compensated navigator (`f64`), fed sample by sample or by
/// arrays.
#[pyclass(module = "delaynav._delaynav")]
struct Navigator {
    nav: Box<DelayCompensatedNav<f64>>,
    config: DelayCompensatedNavConfig<f64>,
}

fn sample_error(e: delaynav::Error) -> PyErr {
    SampleError::new_err(e.to_string())
}

#[pymethods]
impl Navigator {
    #[new]
    #[pyo3(signature = (config=None))]
    fn new(config: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let config = merged_config(DelayCompensatedNavConfig::default(), config)?;
        let nav =
            DelayCompensatedNav::new(config).map_err(|e| ConfigError::new_err(e.to_string()))?;
        Ok(Self {
            nav: Box::new(nav),
            config,
        })
    }

    /// The configuration, as a dict.
    fn config<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        serde_to_py(py, &self.config)
    }

    /// The configuration as TOML (a replay's configuration file).
    fn config_toml(&self) -> PyResult<String> {
        config_to_toml(&self.config).map_err(|e| ConfigError::new_err(e.to_string()))
    }

    fn push_imu(&mut self, t_us: u64, gyro: [f64; 3], accel: [f64; 3]) -> PyResult<()> {
        let imu = Imu::new(t_us, gyro.into(), accel.into());
        self.nav.push_imu(&imu).map_err(sample_error)
    }

    #[pyo3(signature = (t_us, position, velocity_ned, geodetic, horizontal_accuracy_m=None, vertical_accuracy_m=None, speed_accuracy_m_s=None))]
    #[allow(clippy::too_many_arguments)]
    fn push_gps(
        &mut self,
        t_us: u64,
        position: [f64; 3],
        velocity_ned: [f64; 3],
        geodetic: bool,
        horizontal_accuracy_m: Option<f64>,
        vertical_accuracy_m: Option<f64>,
        speed_accuracy_m_s: Option<f64>,
    ) -> PyResult<&'static str> {
        let mut fix = if geodetic {
            let [lat, lon, alt] = position;
            Gps::geodetic(t_us, Geodetic::new(lat, lon, alt), velocity_ned.into())
        } else {
            Gps::ned(t_us, position.into(), velocity_ned.into())
        };
        fix.horizontal_accuracy_m = horizontal_accuracy_m;
        fix.vertical_accuracy_m = vertical_accuracy_m;
        fix.speed_accuracy_m_s = speed_accuracy_m_s;
        Ok(match self.nav.push_gps(&fix).map_err(sample_error)? {
            GpsOutcome::Waiting => "waiting",
            GpsOutcome::Initialized => "initialized",
            GpsOutcome::Fused { .. } => "fused",
            GpsOutcome::Queued => "queued",
        })
    }

    fn push_mag(&mut self, t_us: u64, field_body: [f64; 3]) -> PyResult<&'static str> {
        let mag = Mag::new(t_us, field_body.into());
        Ok(match self.nav.push_mag(&mag).map_err(sample_error)? {
            MagOutcome::Stored => "stored",
            MagOutcome::Fused(_) => "fused",
            MagOutcome::Queued => "queued",
        })
    }

    /// Pushes `n` IMU samples in one call, the loop in Rust (the GIL
    /// released). With `estimates`, returns `(t_us, values)`: after each
    /// sample its time and the estimate flattened (see the Python
    /// wrapper), NaN before the first estimate.
    ///
    /// A sample refused with an error raises [`SampleError`] (index and
    /// time in the message, the samples before it pushed) or, with
    /// `skip_errors`, is counted and the loop goes on. Returns the
    /// estimates (or `None`) and the number of samples skipped.
    #[pyo3(signature = (t_us, gyro, accel, estimates=false, skip_errors=false))]
    fn push_imu_array<'py>(
        &mut self,
        py: Python<'py>,
        t_us: PyReadonlyArray1<'py, u64>,
        gyro: PyReadonlyArray2<'py, f64>,
        accel: PyReadonlyArray2<'py, f64>,
        estimates: bool,
        skip_errors: bool,
    ) -> PyResult<(Option<Bound<'py, PyAny>>, usize)> {
        let (t, g, a) = (t_us.as_array(), gyro.as_array(), accel.as_array());
        let n = t.len();
        if g.shape() != [n, 3] || a.shape() != [n, 3] {
            return Err(PyValueError::new_err(format!(
                "gyro and accel must have shape ({n}, 3) like t_us ({n},); got {:?} and {:?}",
                g.shape(),
                a.shape()
            )));
        }
        // Row-major rows of 3 when contiguous (the Python wrapper makes them so).
        let rows = |v: &numpy::ndarray::ArrayView2<'_, f64>| -> Vec<[f64; 3]> {
            v.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect()
        };
        let (g, a): (Vec<[f64; 3]>, Vec<[f64; 3]>) = match (gyro.as_slice(), accel.as_slice()) {
            (Ok(g), Ok(a)) => (
                g.chunks_exact(3).map(|r| [r[0], r[1], r[2]]).collect(),
                a.chunks_exact(3).map(|r| [r[0], r[1], r[2]]).collect(),
            ),
            _ => (rows(&g), rows(&a)),
        };
        let nav = &mut self.nav;
        let result = py.detach(|| {
            let mut out = Vec::with_capacity(if estimates { n * ESTIMATE_COLUMNS } else { 0 });
            let mut skipped = 0;
            for (i, ((&t_us, gyro), accel)) in t.iter().zip(&g).zip(&a).enumerate() {
                let imu = Imu::new(t_us, (*gyro).into(), (*accel).into());
                match nav.push_imu(&imu) {
                    Ok(()) => {}
                    Err(_) if skip_errors => skipped += 1,
                    Err(e) => return Err(format!("sample {i} (t_us {t_us}): {e}")),
                }
                if estimates {
                    flatten_estimate(nav.estimate().as_ref(), &mut out);
                }
            }
            Ok::<_, String>((out, skipped))
        });
        let (out, skipped) = result.map_err(SampleError::new_err)?;
        Ok((
            estimates.then(|| matrix(py, out, ESTIMATE_COLUMNS)),
            skipped,
        ))
    }

    /// The current estimate as a dict, `None` before initialization.
    fn estimate<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        self.nav
            .estimate()
            .map(|e| estimate_dict(py, &e))
            .transpose()
    }

    /// The navigator's health report, as a dict.
    fn health<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        serde_to_py(py, &self.nav.health())
    }

    /// What the navigator vouches for: protection levels and validity.
    fn integrity<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        serde_to_py(py, &self.nav.integrity())
    }
}

/// Columns of an estimate flattened ([`flatten_estimate`]).
const ESTIMATE_COLUMNS: usize = 1 + 4 + 3 + 3 + 3 + 3 + 16 + 2;

/// `t_us` (as f64), attitude (w x y z), position, velocity, accelerometer
/// bias, gyro bias, covariance diagonal, delay, delay sigma; NaN for none.
fn flatten_estimate(e: Option<&Estimate<f64>>, out: &mut Vec<f64>) {
    let Some(e) = e else {
        out.extend([f64::NAN; ESTIMATE_COLUMNS]);
        return;
    };
    let q = e.attitude.quaternion();
    out.push(e.t_us as f64);
    out.extend([q.w, q.i, q.j, q.k]);
    out.extend(e.position_ned_m.iter());
    out.extend(e.velocity_ned_m_s.iter());
    out.extend(e.accel_bias_m_s2.iter());
    out.extend(e.gyro_bias_rad_s.iter());
    out.extend(e.covariance_diagonal.iter());
    out.push(e.delay_s.unwrap_or(f64::NAN));
    out.push(e.delay_std_s.unwrap_or(f64::NAN));
}

#[pymodule]
fn _delaynav(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add_function(wrap_pyfunction!(replay, m)?)?;
    m.add_function(wrap_pyfunction!(batch, m)?)?;
    m.add_function(wrap_pyfunction!(read_log, m)?)?;
    m.add_class::<Navigator>()?;
    m.add("DelaynavError", py.get_type::<DelaynavError>())?;
    m.add("ConfigError", py.get_type::<ConfigError>())?;
    m.add("LogError", py.get_type::<LogError>())?;
    m.add("SampleError", py.get_type::<SampleError>())?;
    m.add("ESTIMATE_COLUMNS", ESTIMATE_COLUMNS)?;
    Ok(())
}
