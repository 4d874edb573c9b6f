//! One CSV file read row by row: columns found by header name, cells parsed
//! into numbers, and the generic per-file stream that turns rows into
//! samples while counting every row it skips.

use super::{ReplayError, SkipCounts, SkipKind, Timed};
use crate::sensors::check_time;
use csv::StringRecord;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use std::fs::File;
use std::path::{Path, PathBuf};

/// A CSV file with a header row, read one record at a time.
pub(crate) struct CsvTable {
    reader: csv::Reader<File>,
    headers: StringRecord,
    record: StringRecord,
    path: PathBuf,
    label: String,
    finished: bool,
}

impl CsvTable {
    /// Opens `path` and reads its header row.
    pub(crate) fn open(path: &Path) -> Result<Self, ReplayError> {
        let file = File::open(path).map_err(|source| ReplayError::Open {
            path: path.to_path_buf(),
            source,
        })?;
        let mut reader = csv::ReaderBuilder::new()
            .flexible(true)
            .trim(csv::Trim::All)
            .from_reader(file);
        let headers = reader
            .headers()
            .map_err(|source| ReplayError::Header {
                path: path.to_path_buf(),
                source,
            })?
            .clone();
        Ok(Self {
            reader,
            headers,
            record: StringRecord::new(),
            path: path.to_path_buf(),
            label: file_label(path),
            finished: false,
        })
    }

    /// The name the skip report uses for this file (its file name).
    pub(crate) fn label(&self) -> &str {
        &self.label
    }

    /// Index of an optional column.
    pub(crate) fn find(&self, name: &str) -> Option<usize> {
        self.headers.iter().position(|h| h == name)
    }

    /// Index of a required column.
    pub(crate) fn column(&self, name: &str) -> Result<usize, ReplayError> {
        self.find(name).ok_or_else(|| ReplayError::MissingColumn {
            path: self.path.clone(),
            column: name.to_string(),
        })
    }

    /// Indices of three required columns.
    pub(crate) fn columns3(&self, names: [&str; 3]) -> Result<[usize; 3], ReplayError> {
        Ok([
            self.column(names[0])?,
            self.column(names[1])?,
            self.column(names[2])?,
        ])
    }

    /// The first of several alternative column triples that the header
    /// has: its position in `alternatives` and its indices. None present is
    /// a `MissingColumn` error listing them all.
    pub(crate) fn one_of3(
        &self,
        alternatives: &[[&str; 3]],
    ) -> Result<(usize, [usize; 3]), ReplayError> {
        alternatives
            .iter()
            .enumerate()
            .find_map(|(k, names)| self.columns3(*names).ok().map(|idx| (k, idx)))
            .ok_or_else(|| ReplayError::MissingColumn {
                path: self.path.clone(),
                column: alternatives
                    .iter()
                    .map(|a| a.join(","))
                    .collect::<Vec<_>>()
                    .join(" | "),
            })
    }

    /// Indices of four required columns.
    pub(crate) fn columns4(&self, names: [&str; 4]) -> Result<[usize; 4], ReplayError> {
        let [a, b, c] = self.columns3([names[0], names[1], names[2]])?;
        Ok([a, b, c, self.column(names[3])?])
    }

    /// The next record, or `None` at the end of the file. A row the CSV
    /// layer cannot split (bad UTF-8, broken quoting) is counted as
    /// [`SkipKind::Unparsable`]; an I/O error ends the file after counting
    /// the row it broke.
    pub(crate) fn next_record(&mut self, skips: &mut SkipCounts) -> Option<&StringRecord> {
        while !self.finished {
            match self.reader.read_record(&mut self.record) {
                Ok(true) => return Some(&self.record),
                Ok(false) => self.finished = true,
                Err(e) => {
                    skips.skip(&self.label, SkipKind::Unparsable);
                    if matches!(e.kind(), csv::ErrorKind::Io(_)) {
                        self.finished = true;
                    }
                }
            }
        }
        None
    }
}

/// The file name of a path, as the skip report shows it.
pub(crate) fn file_label(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string())
}

fn cell(rec: &StringRecord, idx: usize) -> Result<&str, SkipKind> {
    rec.get(idx).ok_or(SkipKind::Unparsable)
}

/// A required number: missing, empty or malformed is `Unparsable`, NaN or
/// infinite is `NonFinite`.
pub(crate) fn number(rec: &StringRecord, idx: usize) -> Result<f64, SkipKind> {
    let v: f64 = cell(rec, idx)?.parse().map_err(|_| SkipKind::Unparsable)?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(SkipKind::NonFinite)
    }
}

/// An optional number: no column or an empty cell is `None`.
pub(crate) fn optional_number(
    rec: &StringRecord,
    idx: Option<usize>,
) -> Result<Option<f64>, SkipKind> {
    match idx {
        Some(i) if !cell(rec, i)?.is_empty() => number(rec, i).map(Some),
        _ => Ok(None),
    }
}

/// Three required numbers as a vector.
pub(crate) fn vector3(rec: &StringRecord, idx: [usize; 3]) -> Result<Vector3<f64>, SkipKind> {
    Ok(Vector3::new(
        number(rec, idx[0])?,
        number(rec, idx[1])?,
        number(rec, idx[2])?,
    ))
}

/// A scalar-first quaternion `[w, x, y, z]` normalized; a norm far from one
/// (below 0.5) is `OutOfRange`.
pub(crate) fn unit_quaternion(
    rec: &StringRecord,
    idx: [usize; 4],
) -> Result<UnitQuaternion<f64>, SkipKind> {
    let [w, x, y, z] = idx;
    quaternion_wxyz([
        number(rec, w)?,
        number(rec, x)?,
        number(rec, y)?,
        number(rec, z)?,
    ])
}

/// A scalar-first quaternion `[w, x, y, z]` normalized; a norm below 0.5 is
/// `OutOfRange`.
pub(crate) fn quaternion_wxyz(wxyz: [f64; 4]) -> Result<UnitQuaternion<f64>, SkipKind> {
    let [w, x, y, z] = wxyz;
    let q = Quaternion::new(w, x, y, z);
    if q.norm() < 0.5 {
        return Err(SkipKind::OutOfRange);
    }
    Ok(UnitQuaternion::from_quaternion(q))
}

/// An integer microsecond timestamp (`t_us`, PX4 `timestamp`).
pub(crate) fn microseconds(rec: &StringRecord, idx: usize) -> Result<u64, SkipKind> {
    let text = cell(rec, idx)?;
    match text.parse::<u64>() {
        Ok(v) => Ok(v),
        Err(_) if text.parse::<i64>().is_ok() => Err(SkipKind::OutOfRange),
        Err(_) => Err(SkipKind::Unparsable),
    }
}

/// A time in seconds converted to integer microseconds, rounded to nearest:
/// `round(t_s * 1e6)`. Negative times are `OutOfRange`.
pub(crate) fn seconds_as_us(rec: &StringRecord, idx: usize) -> Result<u64, SkipKind> {
    let us = (number(rec, idx)? * 1e6).round();
    if (0.0..u64::MAX as f64).contains(&us) {
        Ok(us as u64)
    } else {
        Err(SkipKind::OutOfRange)
    }
}

/// Turns one CSV row into one output value.
pub(crate) trait RowParser<Out> {
    /// Parses a row. `skips` is there for parsers that read a second file
    /// (the ArduPilot GPS accuracy join) and count its rows.
    fn parse(&mut self, rec: &StringRecord, skips: &mut SkipCounts) -> Result<Out, SkipKind>;
}

/// Where a [`RowStream`]'s values come from.
enum Source<Out> {
    /// A CSV file parsed row by row.
    Csv {
        table: CsvTable,
        parser: Box<dyn RowParser<Out>>,
    },
    /// Records of a binary log already decoded (each one a value or the
    /// reason it is skipped), in the order the log holds them.
    Decoded {
        records: std::vec::IntoIter<Result<Out, SkipKind>>,
        label: String,
    },
}

/// One file's rows (or one binary log's records of one stream) parsed into
/// time-stamped values in increasing time: a row that fails to parse, or
/// whose time is not after the last accepted one, is counted and skipped.
pub(crate) struct RowStream<Out> {
    source: Source<Out>,
    stream: &'static str,
    last_us: Option<u64>,
}

impl<Out: Timed> RowStream<Out> {
    pub(crate) fn new(
        table: CsvTable,
        parser: Box<dyn RowParser<Out>>,
        stream: &'static str,
    ) -> Self {
        Self {
            source: Source::Csv { table, parser },
            stream,
            last_us: None,
        }
    }

    /// A stream over records decoded from a binary log; `label` names them
    /// in the skip report (e.g. `log171.bin:IMU`).
    pub(crate) fn decoded(
        records: Vec<Result<Out, SkipKind>>,
        label: String,
        stream: &'static str,
    ) -> Self {
        Self {
            source: Source::Decoded {
                records: records.into_iter(),
                label,
            },
            stream,
            last_us: None,
        }
    }

    /// The next accepted value, or `None` when the file is exhausted.
    pub(crate) fn next_value(&mut self, skips: &mut SkipCounts) -> Option<Out> {
        loop {
            let outcome = match &mut self.source {
                Source::Csv { table, parser } => {
                    let rec = table.next_record(skips)?;
                    parser.parse(rec, skips)
                }
                Source::Decoded { records, .. } => records.next()?,
            };
            let outcome = outcome.and_then(|value| {
                check_time(self.stream, self.last_us, value.time_us())
                    .map(|()| value)
                    .map_err(SkipKind::from)
            });
            match outcome {
                Ok(value) => {
                    self.last_us = Some(value.time_us());
                    skips.accept(self.label());
                    return Some(value);
                }
                Err(kind) => skips.skip(self.label(), kind),
            }
        }
    }

    /// The file name this stream reads.
    pub(crate) fn label(&self) -> &str {
        match &self.source {
            Source::Csv { table, .. } => table.label(),
            Source::Decoded { label, .. } => label,
        }
    }
}
