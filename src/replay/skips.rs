//! The report of every reader: rows accepted and skipped, by file and by
//! [`SkipKind`] (see the module docs of [`crate::replay`], "Bad rows").

use crate::error::Error;
use std::collections::BTreeMap;
use std::fmt;

/// Why a row was skipped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum SkipKind {
    /// A cell is missing, empty where a value is required, or not a number.
    Unparsable,
    /// A value is NaN or infinite.
    NonFinite,
    /// A value is outside its valid range (negative time, latitude beyond
    /// 90 deg, zero magnetic field, non-positive accuracy).
    OutOfRange,
    /// The logger flagged the sample invalid (unhealthy magnetometer,
    /// invalid relative timestamp, GPS velocity marked not valid).
    Invalid,
    /// A GPS row without a 3-D fix.
    NoFix,
    /// The row's time is earlier than the previous accepted row of its file.
    TimeWentBackwards,
    /// The row repeats the previous accepted row's timestamp.
    Duplicate,
}

impl SkipKind {
    /// Every kind, in report order.
    pub const ALL: [SkipKind; 7] = [
        Self::Unparsable,
        Self::NonFinite,
        Self::OutOfRange,
        Self::Invalid,
        Self::NoFix,
        Self::TimeWentBackwards,
        Self::Duplicate,
    ];

    /// A short snake_case name for reports and JSON keys.
    pub fn name(self) -> &'static str {
        match self {
            Self::Unparsable => "unparsable",
            Self::NonFinite => "non_finite",
            Self::OutOfRange => "out_of_range",
            Self::Invalid => "invalid",
            Self::NoFix => "no_fix",
            Self::TimeWentBackwards => "time_went_backwards",
            Self::Duplicate => "duplicate",
        }
    }

    fn index(self) -> usize {
        self as usize
    }
}

impl fmt::Display for SkipKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl From<Error> for SkipKind {
    /// How a sample refused by the crate's checks is counted.
    fn from(e: Error) -> Self {
        match e {
            Error::NonFinite { .. } => Self::NonFinite,
            Error::TimeWentBackwards { .. } => Self::TimeWentBackwards,
            Error::DuplicateTimestamp { .. } => Self::Duplicate,
            _ => Self::OutOfRange,
        }
    }
}

/// Rows accepted and skipped in one file.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FileCounts {
    /// Rows turned into samples.
    pub accepted: u64,
    skipped: [u64; SkipKind::ALL.len()],
}

impl FileCounts {
    /// Rows skipped for `kind`.
    pub fn skipped(&self, kind: SkipKind) -> u64 {
        self.skipped[kind.index()]
    }

    /// Rows skipped for any reason.
    pub fn skipped_total(&self) -> u64 {
        self.skipped.iter().sum()
    }
}

/// The report of every reader: rows accepted and skipped, by file and by kind.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SkipCounts {
    files: BTreeMap<String, FileCounts>,
}

impl SkipCounts {
    /// Counts one skipped row of `file`.
    pub fn skip(&mut self, file: &str, kind: SkipKind) {
        self.entry(file).skipped[kind.index()] += 1;
    }

    /// Counts one accepted row of `file`.
    pub fn accept(&mut self, file: &str) {
        self.entry(file).accepted += 1;
    }

    fn entry(&mut self, file: &str) -> &mut FileCounts {
        if !self.files.contains_key(file) {
            self.files.insert(file.to_string(), FileCounts::default());
        }
        self.files.get_mut(file).expect("inserted above")
    }

    /// Rows skipped for `kind`, all files together.
    pub fn count(&self, kind: SkipKind) -> u64 {
        self.files.values().map(|c| c.skipped(kind)).sum()
    }

    /// Rows skipped for any reason, all files together.
    pub fn total(&self) -> u64 {
        self.files.values().map(FileCounts::skipped_total).sum()
    }

    /// The counts of one file (by file name), if it was read.
    pub fn file(&self, file: &str) -> Option<&FileCounts> {
        self.files.get(file)
    }

    /// Every file read, by name.
    pub fn files(&self) -> impl Iterator<Item = (&str, &FileCounts)> {
        self.files.iter().map(|(k, v)| (k.as_str(), v))
    }

    /// Kinds with a non-zero count and their totals, in [`SkipKind::ALL`] order.
    pub fn by_kind(&self) -> Vec<(SkipKind, u64)> {
        SkipKind::ALL
            .iter()
            .map(|&k| (k, self.count(k)))
            .filter(|&(_, n)| n > 0)
            .collect()
    }
}

impl fmt::Display for SkipCounts {
    /// One line per file: `gps.csv: 1038 accepted, 161 skipped (no_fix 161)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (name, c) in &self.files {
            write!(
                f,
                "{name}: {} accepted, {} skipped",
                c.accepted,
                c.skipped_total()
            )?;
            let kinds: Vec<String> = SkipKind::ALL
                .iter()
                .filter(|&&k| c.skipped(k) > 0)
                .map(|&k| format!("{k} {}", c.skipped(k)))
                .collect();
            if !kinds.is_empty() {
                write!(f, " ({})", kinds.join(", "))?;
            }
            writeln!(f)?;
        }
        Ok(())
    }
}
