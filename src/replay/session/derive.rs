//! What a replay derives from the log before it runs an estimator: the
//! flight window, the sensors' rates, accuracy and noise, the date, the
//! Earth's field, the mounting trim; each value with where it came from.

use super::{DEFAULT_WARMUP_S, ReplayOptions, ReplaySetup, seconds_to_us_clamped};
use crate::replay::defaults::{NoiseMeasurement, time::Date};
use crate::replay::{
    ArduPilotImu, DelayStep, FlightWindow, ImuNoise, LogDefaults, LogFiles, LogFormat, LogReader,
    MagneticModel, NoiseSource, ReaderOptions, ReferenceAlignment, ReplayError, RunOptions,
    SkipCounts, ardupilot, dataflash::DataFlashLog, flight_window, inclination_at_rest, log_date,
    magnetic_model,
};
use crate::{DelayCompensatedNavConfig, Ekf16Config};
use serde_json::{Value, json};
use std::fmt;

/// Where the IMU noise density the filters get comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoiseChoice {
    /// Given in the options ([`ReplayOptions::accel_noise_density`],
    /// [`ReplayOptions::gyro_noise_density`]).
    Given,
    /// Measured on the log ([`LogDefaults::imu_noise`]).
    Measured(NoiseSource),
}

/// Where the magnetic declination comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeclinationSource {
    /// Given in the options ([`ReplayOptions::declination_deg`]).
    Given,
    /// ArduPilot's `COMPASS_DEC`, the log's own manual setting
    /// (`COMPASS_AUTODEC = 0`).
    LogParameter,
    /// The World Magnetic Model at the first fix on the log's date.
    MagneticModel,
    /// The World Magnetic Model at the nearest date it covers (the log's is
    /// outside 2020-2029).
    MagneticModelNearestDate,
    /// Nothing to derive it from (no date or no geodetic fix): 0.
    None,
}

/// Where the magnetic inclination comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InclinationSource {
    /// Given in the options ([`ReplayOptions::inclination_deg`]).
    Given,
    /// Measured over the stationary segment ([`inclination_at_rest`]).
    StationarySegment,
    /// The World Magnetic Model.
    MagneticModel,
    /// Measured over the log's first 10 s (no segment and no model).
    FirstSeconds,
    /// Nothing to measure it on (no magnetometer sample in the log's first
    /// 10 s) and no model: 0, used by nothing that reads a magnetometer.
    None,
}

/// The text the summary and the JSON give for [`ReplayOptions`] values.
const GIVEN: &str = "command line";

impl NoiseChoice {
    /// As in the JSON (`"command line"`, else [`NoiseSource::name`]).
    pub fn name(self) -> &'static str {
        match self {
            Self::Given => GIVEN,
            Self::Measured(source) => source.name(),
        }
    }
}

impl DeclinationSource {
    /// As in the JSON (`"declination_source"`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Given => GIVEN,
            Self::LogParameter => "log parameter COMPASS_DEC (COMPASS_AUTODEC = 0)",
            Self::MagneticModel => "World Magnetic Model",
            Self::MagneticModelNearestDate => "World Magnetic Model at the nearest date it covers",
            Self::None => "none (0)",
        }
    }
}

impl InclinationSource {
    /// As in the JSON (`"inclination_source"`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Given => GIVEN,
            Self::StationarySegment => "stationary segment",
            Self::MagneticModel => "World Magnetic Model",
            Self::FirstSeconds => "the log's first 10 s",
            Self::None => "none (0: no magnetometer sample to measure it on)",
        }
    }
}

/// A note on what the setup found or chose, in the order it was found: the
/// console prints each as one line (the texts name the command line's
/// flags, as the options' fields do).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SetupNote {
    /// The flight window found in the log; `overridden` when
    /// [`ReplayOptions::from_s`] or [`ReplayOptions::to_s`] replace it.
    FlightWindow {
        /// The window.
        window: FlightWindow,
        /// The options bound the window instead.
        overridden: bool,
    },
    /// No fix shows the vehicle moving: the whole log is scored.
    NoFlight,
    /// Warning: the log's date is outside the World Magnetic Model's.
    ModelDateClamped {
        /// The log's date.
        log_date: Date,
        /// The date the model was evaluated at.
        model_date: Date,
    },
    /// Warning: no date or no geodetic fix, declination 0.
    NoDeclination,
    /// Warning: the measured inclination is more than 10 deg from the
    /// model's (it is used).
    InclinationFarFromModel {
        /// The inclination used, radians.
        inclination_rad: f64,
        /// Where it comes from.
        source: InclinationSource,
        /// The model's, radians.
        model_rad: f64,
    },
}

impl fmt::Display for SetupNote {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = |t: u64| t as f64 * 1e-6;
        match *self {
            Self::FlightWindow { window: w, overridden } => write!(
                f,
                "flight window from the log: {:.1}-{:.1} s (take-off {:.1} s, landing {:.1} s, {}){}",
                s(w.from_us),
                s(w.to_us),
                s(w.from_us),
                s(w.landing_us),
                match (w.impact_us, w.loss_of_control_us) {
                    (None, _) => "no impact".to_string(),
                    (Some(t), None) => format!("impact at {:.1} s, cut 2 s before", s(t)),
                    (Some(t), Some(l)) => format!(
                        "impact at {:.1} s, cut at the loss of control, {:.1} s, or 2 s before",
                        s(t),
                        s(l)
                    ),
                },
                if overridden { "; --from/--to override it" } else { "" },
            ),
            Self::NoFlight => {
                f.write_str("no flight found in the log (no GPS fix moving): scoring the whole log")
            }
            Self::ModelDateClamped {
                log_date,
                model_date,
            } => write!(
                f,
                "warning: the log is dated {log_date}, outside the World Magnetic Model's \
                 2020-2029: its field is evaluated at {model_date} (the nearest date it covers); \
                 give --declination-deg to set it"
            ),
            Self::NoDeclination => f.write_str(
                "warning: no date or no geodetic fix in the log: declination 0 (give --declination-deg)",
            ),
            Self::InclinationFarFromModel {
                inclination_rad,
                source,
                model_rad,
            } => write!(
                f,
                "warning: the magnetometer's inclination ({:.1} deg, {}) is {:.1} deg from the \
                 World Magnetic Model's ({:.1} deg): uncalibrated or disturbed magnetometer? The \
                 measured value is used (give --inclination-deg to set it)",
                inclination_rad.to_degrees(),
                source.name(),
                (inclination_rad - model_rad).abs().to_degrees(),
                model_rad.to_degrees()
            ),
        }
    }
}

/// Every value measured on the log and chosen from it, with its source:
/// the JSON's `"derived"` ([`Self::to_json`]) and the console's "derived
/// from the log" lines (`Display`). Fixed before a configuration file is
/// merged.
#[derive(Debug, Clone, PartialEq)]
pub struct DerivedDefaults {
    /// What the log says about its sensors.
    pub measured: LogDefaults,
    /// The filters' IMU noise.
    pub imu_noise: ImuNoise,
    /// Where the accelerometer's and the gyro's densities come from (as
    /// [`LogDefaults::imu_noise`] gives them).
    pub imu_noise_sources: [NoiseChoice; 2],
    /// The log's date, if it has one ([`log_date`]).
    pub log_date: Option<Date>,
    /// The World Magnetic Model at the first fix on that date.
    pub model: Option<MagneticModel>,
    /// Declination, radians east, and where it comes from.
    pub declination_rad: (f64, DeclinationSource),
    /// Inclination, radians down, and where it comes from.
    pub inclination_rad: (f64, InclinationSource),
}

impl DerivedDefaults {
    /// The JSON's `"derived"` object: `imu_rate_hz`, `gps_rate_hz`,
    /// `mag_rate_hz`, `gps_accuracy_reported_median` (`horizontal_m`,
    /// `vertical_m`, `speed_m_s`), `stationary_segment` and `in_flight`
    /// (`from_s`, `to_s`, `accel_density_per_axis`, `gyro_density_per_axis`),
    /// `accel_noise_density`, `accel_noise_source`, `gyro_noise_density`,
    /// `gyro_noise_source`, `log_date`, `first_fix` (`[lat, lon, alt]`),
    /// `model` (`declination_deg`, `declination_std_deg`, `inclination_deg`,
    /// `evaluated_at`, `date_clamped`), `declination_deg`,
    /// `declination_source`, `inclination_deg`, `inclination_source`;
    /// `null` for what the log does not give.
    pub fn to_json(&self) -> Value {
        let m = &self.measured;
        let segment = |m: Option<NoiseMeasurement>| {
            m.map(|m| {
                json!({
                    "from_s": m.from_us as f64 * 1e-6,
                    "to_s": m.to_us as f64 * 1e-6,
                    "accel_density_per_axis": m.accel_density,
                    "gyro_density_per_axis": m.gyro_density,
                })
            })
        };
        json!({
            "imu_rate_hz": m.imu_rate_hz,
            "gps_rate_hz": m.gps_rate_hz,
            "mag_rate_hz": m.mag_rate_hz,
            "gps_accuracy_reported_median": {
                "horizontal_m": m.gps_horizontal_accuracy_m,
                "vertical_m": m.gps_vertical_accuracy_m,
                "speed_m_s": m.gps_speed_accuracy_m_s,
            },
            "stationary_segment": segment(m.stationary),
            "in_flight": segment(m.in_flight),
            "accel_noise_density": self.imu_noise.accel_noise_density,
            "accel_noise_source": self.imu_noise_sources[0].name(),
            "gyro_noise_density": self.imu_noise.gyro_noise_density,
            "gyro_noise_source": self.imu_noise_sources[1].name(),
            "log_date": self.log_date.map(|d| d.to_string()),
            "first_fix": m.first_fix.map(|g| [g.lat_deg, g.lon_deg, g.alt_m]),
            "model": self.model.map(|m| json!({
                "declination_deg": m.declination_rad.to_degrees(),
                "declination_std_deg": m.declination_std_rad.to_degrees(),
                "inclination_deg": m.inclination_rad.to_degrees(),
                "evaluated_at": m.model_date.to_string(),
                "date_clamped": m.date_clamped,
            })),
            "declination_deg": self.declination_rad.0.to_degrees(),
            "declination_source": self.declination_rad.1.name(),
            "inclination_deg": self.inclination_rad.0.to_degrees(),
            "inclination_source": self.inclination_rad.1.name(),
        })
    }
}

/// `v` with `digits` decimals; `-` for none or a value the JSON cannot hold
/// (NaN, infinity: `null` there).
pub(super) fn num(v: Option<f64>, digits: usize) -> String {
    v.filter(|x| x.is_finite())
        .map_or_else(|| "-".to_string(), |x| format!("{x:.digits$}"))
}

impl fmt::Display for DerivedDefaults {
    /// The derived values, one line each, as the console prints them at the
    /// start of a replay.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let m = &self.measured;
        writeln!(
            f,
            "derived from the log (docs/replay.md, \"Defaults from the log\"):"
        )?;
        let [imu, gps, mag] = [(m.imu_rate_hz, 1), (m.gps_rate_hz, 2), (m.mag_rate_hz, 2)]
            .map(|(rate, digits)| num(rate, digits));
        writeln!(
            f,
            "  rates: IMU {imu} Hz, GPS {gps} Hz, magnetometer {mag} Hz (median intervals)"
        )?;
        let finite = |v: Option<f64>| v.filter(|x| x.is_finite());
        if finite(m.gps_horizontal_accuracy_m).is_none()
            && finite(m.gps_speed_accuracy_m_s).is_none()
        {
            writeln!(
                f,
                "  GPS accuracy: not reported by the log: the filters' defaults"
            )?;
        } else {
            let [h, v, speed] = [
                m.gps_horizontal_accuracy_m,
                m.gps_vertical_accuracy_m,
                m.gps_speed_accuracy_m_s,
            ]
            .map(|a| num(a, 2));
            writeln!(
                f,
                "  GPS accuracy: reported per fix, median horizontal {h} m, vertical {v} m, speed {speed} m/s"
            )?;
        }
        for (label, segment) in [
            ("stationary segment", m.stationary),
            ("in flight", m.in_flight),
        ] {
            let Some(s) = segment else {
                writeln!(f, "  {label}: none")?;
                continue;
            };
            let axes = |a: [f64; 3], digits: usize| a.map(|v| num(Some(v), digits)).join("/");
            writeln!(
                f,
                "  {label} {}-{} s: accel {} m/s^2/sqrt(Hz), gyro {} rad/s/sqrt(Hz) (x/y/z)",
                num(Some(s.from_us as f64 * 1e-6), 1),
                num(Some(s.to_us as f64 * 1e-6), 1),
                axes(s.accel_density, 4),
                axes(s.gyro_density, 5)
            )?;
        }
        writeln!(
            f,
            "  IMU noise used: accel {} ({}), gyro {} ({})",
            num(Some(self.imu_noise.accel_noise_density), 4),
            self.imu_noise_sources[0].name(),
            num(Some(self.imu_noise.gyro_noise_density), 5),
            self.imu_noise_sources[1].name()
        )?;
        writeln!(
            f,
            "  declination {} deg ({}), inclination {} deg ({}); log date {}, first fix {}",
            num(Some(self.declination_rad.0.to_degrees()), 2),
            self.declination_rad.1.name(),
            num(Some(self.inclination_rad.0.to_degrees()), 2),
            self.inclination_rad.1.name(),
            self.log_date
                .map_or_else(|| "unknown".to_string(), |d| d.to_string()),
            m.first_fix.map_or_else(
                || "none".to_string(),
                |g| format!("{} {}", num(Some(g.lat_deg), 5), num(Some(g.lon_deg), 5))
            )
        )
    }
}

/// Reads the log named by `options` and derives everything the replay
/// needs from it ([`ReplaySetup::from_log`]).
pub(super) fn derive(options: &ReplayOptions) -> Result<ReplaySetup, ReplayError> {
    let imu_instance = options.imu_instance;
    let reader = ReaderOptions {
        ardupilot_imu: match imu_instance {
            0 => ArduPilotImu::First,
            _ => ArduPilotImu::Second,
        },
        imu_instance,
        drop_mag: options.no_mag,
        ..ReaderOptions::default()
    }
    .with_added_gps_delay(options.add_gps_delay_s, options.add_delay_from_s)?;
    let files = LogFiles::locate(&options.inputs, options.format, &reader)?;
    if files.format == LogFormat::ArduPilot && imu_instance > 1 {
        return Err(ReplayError::NoSuchImu {
            instance: imu_instance,
        });
    }
    let open = || LogReader::<f64>::open(&files, &reader);
    let mut notes = Vec::new();

    // The flight window: found in the log, unless the options fix it.
    let window = if !options.fixed_window {
        let window = flight_window(open()?);
        notes.push(match window {
            Some(window) => SetupNote::FlightWindow {
                window,
                overridden: options.from_s.is_some() || options.to_s.is_some(),
            },
            None => SetupNote::NoFlight,
        });
        window
    } else {
        None
    };
    let measured = LogDefaults::measure(open()?, window.as_ref());
    let imu_rate_hz = measured
        .imu_rate_hz
        .unwrap_or(DelayCompensatedNavConfig::<f64>::default().imu_rate_hz);
    let gps_rate_hz = measured.gps_rate_hz.filter(|r| (1.0..=20.0).contains(r));

    // IMU noise: measured (never below the filters' defaults), options override.
    let defaults = Ekf16Config::<f64>::default();
    let (noise, [accel_source, gyro_source]) = measured.imu_noise(ImuNoise {
        accel_noise_density: defaults.accel_noise_density,
        gyro_noise_density: defaults.gyro_noise_density,
    });
    let given = [options.accel_noise_density, options.gyro_noise_density];
    let imu_noise = ImuNoise {
        accel_noise_density: given[0].unwrap_or(noise.accel_noise_density),
        gyro_noise_density: given[1].unwrap_or(noise.gyro_noise_density),
    };
    let source = |given: Option<f64>, s: NoiseSource| {
        given.map_or(NoiseChoice::Measured(s), |_| NoiseChoice::Given)
    };

    // Declination: the option, else the autopilot's own manual setting, else
    // the World Magnetic Model at the first fix on the log's date.
    let date = log_date(&files)?;
    let model: Option<MagneticModel> = measured
        .first_fix
        .zip(date)
        .and_then(|(place, date)| magnetic_model(&place, date));
    if let (Some(m), Some(date)) = (model, date)
        && m.date_clamped
    {
        notes.push(SetupNote::ModelDateClamped {
            log_date: date,
            model_date: m.model_date,
        });
    }
    let params = match (&files.params, files.format) {
        (Some(path), LogFormat::DataFlash) => Some(DataFlashLog::open(path)?.params()),
        (Some(path), LogFormat::ArduPilot) => {
            Some(ardupilot::read_params(path, &mut SkipCounts::default())?)
        }
        _ => None,
    };
    let model_declination = model.map_or(0.0, |m| m.declination_rad);
    let mut alignment = match &params {
        Some(values) => ardupilot::alignment_from_params(values, model_declination),
        None => ReferenceAlignment {
            declination_rad: model_declination,
            ..ReferenceAlignment::default()
        },
    };
    let manual_declination = params
        .as_ref()
        .is_some_and(|p| p.get("COMPASS_AUTODEC") == Some(&0.0) && p.contains_key("COMPASS_DEC"));
    let declination_source = if options.declination_deg.is_some() {
        DeclinationSource::Given
    } else if manual_declination {
        DeclinationSource::LogParameter
    } else if model.is_some_and(|m| m.date_clamped) {
        DeclinationSource::MagneticModelNearestDate
    } else if model.is_some() {
        DeclinationSource::MagneticModel
    } else {
        notes.push(SetupNote::NoDeclination);
        DeclinationSource::None
    };
    if let Some(d) = options.declination_deg {
        alignment.declination_rad = d.to_radians();
    }
    let [roll, pitch] = options.trim_rad;
    alignment.trim_roll_rad = roll.unwrap_or(alignment.trim_roll_rad);
    alignment.trim_pitch_rad = pitch.unwrap_or(alignment.trim_pitch_rad);

    // Inclination: the option, else measured over the stationary segment,
    // else the model, else measured over the log's first 10 s.
    let (inclination_rad, inclination_source) = match (options.inclination_deg, measured.stationary)
    {
        (Some(i), _) => (i.to_radians(), InclinationSource::Given),
        (None, Some(still)) => {
            let events = open()?.skip_while(move |e| e.time_us() < still.from_us);
            match inclination_at_rest(events, still.to_us - still.from_us) {
                Some(i) => (i, InclinationSource::StationarySegment),
                None => (
                    model.map_or(0.0, |m| m.inclination_rad),
                    InclinationSource::MagneticModel,
                ),
            }
        }
        (None, None) => match model {
            Some(m) => (m.inclination_rad, InclinationSource::MagneticModel),
            None => inclination_at_rest(open()?, 10_000_000)
                .map_or((0.0, InclinationSource::None), |i| {
                    (i, InclinationSource::FirstSeconds)
                }),
        },
    };
    if let Some(m) = model
        && (m.inclination_rad - inclination_rad).abs() > 10f64.to_radians()
    {
        notes.push(SetupNote::InclinationFarFromModel {
            inclination_rad,
            source: inclination_source,
            model_rad: m.inclination_rad,
        });
    }
    let gps_accuracy = [
        measured.gps_horizontal_accuracy_m,
        measured.gps_vertical_accuracy_m,
        measured.gps_speed_accuracy_m_s,
    ];
    let from_s = options.from_s.or(window.map(|w| w.from_us as f64 * 1e-6));
    let to_s = options.to_s.or(window.map(|w| w.to_us as f64 * 1e-6));
    let warmup_s = options.warmup_s.unwrap_or(DEFAULT_WARMUP_S);
    let run = RunOptions {
        start_us: from_s.map(|f| seconds_to_us_clamped(f - warmup_s)),
        score_from_us: from_s.map(seconds_to_us_clamped),
        end_us: to_s.map(seconds_to_us_clamped),
        alignment,
        estimator_declination_rad: alignment.declination_rad,
        delay_step: options
            .add_delay_from_s
            .map(|_| DelayStep::new(reader.gps_delay_added_from_us, options.add_gps_delay_s)),
        ..RunOptions::default()
    };
    let derived = DerivedDefaults {
        measured,
        imu_noise,
        imu_noise_sources: [
            source(options.accel_noise_density, accel_source),
            source(options.gyro_noise_density, gyro_source),
        ],
        log_date: date,
        model,
        declination_rad: (alignment.declination_rad, declination_source),
        inclination_rad: (inclination_rad, inclination_source),
    };
    let mut setup = ReplaySetup {
        options: options.clone(),
        files,
        reader,
        run,
        window,
        declination_rad: alignment.declination_rad,
        inclination_rad,
        imu_rate_hz,
        gps_rate_hz,
        imu_noise,
        accel_bias_random_walk: options
            .accel_bias_random_walk
            .unwrap_or(defaults.accel_bias_random_walk),
        gps_accuracy,
        nav: DelayCompensatedNavConfig::default(),
        derived,
        notes,
    };
    setup.nav = setup.log_config()?;
    Ok(setup)
}
