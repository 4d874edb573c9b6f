//! Writes a simulated run as a log directory in the crate's CSV format
//! (`docs/csv-format.md`): `imu.csv`, `gps.csv`, `mag.csv`, `truth.csv`.
//!
//! Numbers are written with Rust's shortest round-trip formatting, so a
//! reader parsing them with `str::parse::<f64>` gets the simulated values
//! back bit for bit. GPS positions go to `pos_n_m, pos_e_m, pos_d_m` or to
//! `lat_deg, lon_deg, alt_m`, whichever the fix carries (one file holds one
//! kind: the first fix decides, and a fix of the other kind is an error).
//! Receiver accuracies are written when the fix reports them, else left
//! empty.

use super::{SimEvent, Truth};
use crate::sensors::{Gps, GpsPosition, Imu, Mag};
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

/// Header of `imu.csv`.
pub const IMU_HEADER: &str =
    "t_us,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,acc_x_m_s2,acc_y_m_s2,acc_z_m_s2";
/// Header of `gps.csv` with NED positions.
pub const GPS_NED_HEADER: &str =
    "t_us,pos_n_m,pos_e_m,pos_d_m,vel_n_m_s,vel_e_m_s,vel_d_m_s,h_acc_m,v_acc_m,s_acc_m_s";
/// Header of `gps.csv` with geodetic positions.
pub const GPS_GEODETIC_HEADER: &str =
    "t_us,lat_deg,lon_deg,alt_m,vel_n_m_s,vel_e_m_s,vel_d_m_s,h_acc_m,v_acc_m,s_acc_m_s";
/// Header of `mag.csv`.
pub const MAG_HEADER: &str = "t_us,mag_x,mag_y,mag_z";
/// Header of `truth.csv`.
pub const TRUTH_HEADER: &str = "t_us,q0,q1,q2,q3,roll_rad,pitch_rad,yaw_rad,pos_n_m,pos_e_m,pos_d_m,\
vel_n_m_s,vel_e_m_s,vel_d_m_s,acc_n_m_s2,acc_e_m_s2,acc_d_m_s2,\
gyro_bias_x_rad_s,gyro_bias_y_rad_s,gyro_bias_z_rad_s,acc_bias_x_m_s2,acc_bias_y_m_s2,acc_bias_z_m_s2,gps_delay_s";

fn optional(x: Option<f64>) -> String {
    x.map(|v| v.to_string()).unwrap_or_default()
}

/// Streams events into the four files of a log directory.
#[derive(Debug)]
pub struct CsvLogWriter {
    imu: BufWriter<File>,
    gps: BufWriter<File>,
    mag: BufWriter<File>,
    truth: BufWriter<File>,
    gps_geodetic: Option<bool>,
}

impl CsvLogWriter {
    /// Creates the directory (and parents) and the four files with their
    /// headers; `gps.csv` gets its header with the first fix.
    pub fn create(dir: &Path) -> io::Result<Self> {
        std::fs::create_dir_all(dir)?;
        let open = |name: &str| File::create(dir.join(name)).map(BufWriter::new);
        let mut w = Self {
            imu: open("imu.csv")?,
            gps: open("gps.csv")?,
            mag: open("mag.csv")?,
            truth: open("truth.csv")?,
            gps_geodetic: None,
        };
        writeln!(w.imu, "{IMU_HEADER}")?;
        writeln!(w.mag, "{MAG_HEADER}")?;
        writeln!(w.truth, "{TRUTH_HEADER}")?;
        Ok(w)
    }

    /// Writes one event.
    pub fn write(&mut self, event: &SimEvent) -> io::Result<()> {
        match event {
            SimEvent::Imu { sample, truth } => {
                self.write_imu(sample)?;
                self.write_truth(truth)
            }
            SimEvent::Mag(m) => self.write_mag(m),
            SimEvent::Gps { fix, .. } => self.write_gps(fix),
        }
    }

    fn write_imu(&mut self, s: &Imu<f64>) -> io::Result<()> {
        let (g, a) = (s.gyro_rad_s, s.accel_m_s2);
        writeln!(
            self.imu,
            "{},{},{},{},{},{},{}",
            s.t_us, g.x, g.y, g.z, a.x, a.y, a.z
        )
    }

    fn write_mag(&mut self, m: &Mag<f64>) -> io::Result<()> {
        let f = m.field_body;
        writeln!(self.mag, "{},{},{},{}", m.t_us, f.x, f.y, f.z)
    }

    fn write_gps(&mut self, fix: &Gps<f64>) -> io::Result<()> {
        let geodetic = matches!(fix.position, GpsPosition::Geodetic(_));
        match self.gps_geodetic {
            None => {
                let header = if geodetic {
                    GPS_GEODETIC_HEADER
                } else {
                    GPS_NED_HEADER
                };
                writeln!(self.gps, "{header}")?;
                self.gps_geodetic = Some(geodetic);
            }
            Some(kind) if kind != geodetic => {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidInput,
                    "gps.csv holds one kind of position: NED and geodetic fixes mixed",
                ));
            }
            Some(_) => {}
        }
        let (a, b, c) = match fix.position {
            GpsPosition::Ned(p) => (p.x, p.y, p.z),
            GpsPosition::Geodetic(g) => (g.lat_deg, g.lon_deg, g.alt_m),
        };
        let v = fix.velocity_ned_m_s;
        writeln!(
            self.gps,
            "{},{},{},{},{},{},{},{},{},{}",
            fix.t_us,
            a,
            b,
            c,
            v.x,
            v.y,
            v.z,
            optional(fix.horizontal_accuracy_m),
            optional(fix.vertical_accuracy_m),
            optional(fix.speed_accuracy_m_s)
        )
    }

    fn write_truth(&mut self, t: &Truth) -> io::Result<()> {
        let q = t.attitude.quaternion();
        let e = t.euler_rad;
        let mut line = format!(
            "{},{},{},{},{},{},{},{}",
            t.t_us, q.w, q.i, q.j, q.k, e.x, e.y, e.z
        );
        for v in [
            t.position_m,
            t.velocity_m_s,
            t.accel_m_s2,
            t.gyro_bias_rad_s,
            t.accel_bias_m_s2,
        ] {
            line.push_str(&format!(",{},{},{}", v.x, v.y, v.z));
        }
        writeln!(self.truth, "{line},{}", t.gps_delay_s)
    }

    /// Flushes the four files (a run without fixes gets the NED header).
    pub fn finish(mut self) -> io::Result<()> {
        if self.gps_geodetic.is_none() {
            writeln!(self.gps, "{GPS_NED_HEADER}")?;
        }
        self.imu.flush()?;
        self.gps.flush()?;
        self.mag.flush()?;
        self.truth.flush()
    }
}

/// Writes a whole run into `dir`; returns the number of events written.
pub fn write_run<I: IntoIterator<Item = SimEvent>>(dir: &Path, events: I) -> io::Result<usize> {
    let mut writer = CsvLogWriter::create(dir)?;
    let mut n = 0;
    for event in events {
        writer.write(&event)?;
        n += 1;
    }
    writer.finish()?;
    Ok(n)
}
