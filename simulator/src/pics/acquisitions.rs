//! The acquisitions CSV of `simulate pics`: one row per acquisition, read with the `csv` crate.
//!
//! | column     | required | unit | range        | meaning                                              |
//! |------------|----------|------|--------------|------------------------------------------------------|
//! | `time_utc` | yes      | —    | RFC 3339     | `2026-06-15T09:45:00Z` or `…T11:45:00+02:00` (to UTC)  |
//! | `vza`      | yes      | deg  | [0, 90]      | view zenith angle                                    |
//! | `vaa`      | yes      | deg  | [−360, 360]  | view azimuth, clockwise from North, site → sensor    |
//! | `srf`      | yes      | —    | —            | an embedded SRF name or an SRF CSV file              |
//! | `sza`      | no       | deg  | [0, 180]     | solar zenith: replaces the one from NREL SPA         |
//! | `saa`      | no       | deg  | [−360, 360]  | solar azimuth, clockwise from North (with `sza`)     |
//!
//! `sza` and `saa` go together; an empty cell in either column means "computed" for that row.
//! Unknown columns are errors (a misspelt `sza` must not be ignored silently). Lines starting
//! with `#` are comments. Every error names the file, the line and the column.

use std::path::Path;

use engine::error::ConfigError;
use engine::sources::sun_position::{format_utc, parse_time};

/// One acquisition.
#[derive(Clone, Debug, PartialEq)]
pub struct Acquisition {
    /// UTC time, `YYYY-MM-DDTHH:MM:SS[.f]Z` (RFC 3339; `Acquisition::new` normalises offsets).
    pub time_utc: String,
    /// View zenith angle, degrees.
    pub vza: f64,
    /// View azimuth, degrees clockwise from North (direction site → sensor).
    pub vaa: f64,
    /// SRF name or file.
    pub srf: String,
    /// Solar zenith and azimuth (degrees) given by the user; `None`: from NREL SPA at the time.
    pub sun: Option<(f64, f64)>,
}

impl Acquisition {
    /// An acquisition with the Sun computed from `time` (RFC 3339, any offset).
    pub fn new(time: &str, vza: f64, vaa: f64, srf: &str) -> Result<Self, String> {
        Ok(Acquisition {
            time_utc: format_utc(&parse_time(time).map_err(|e| e.to_string())?),
            vza,
            vaa,
            srf: srf.to_string(),
            sun: None,
        })
    }
}

const REQUIRED: [&str; 4] = ["time_utc", "vza", "vaa", "srf"];
const OPTIONAL: [&str; 2] = ["sza", "saa"];

/// Parse the acquisitions CSV; errors name the file, the line and the column.
pub fn read_acquisitions(path: &Path) -> Result<Vec<Acquisition>, ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
        path: path.into(),
        source,
    })?;
    parse_acquisitions(&text, path)
}

/// Parse acquisitions CSV text; `path` names it in errors.
pub fn parse_acquisitions(text: &str, path: &Path) -> Result<Vec<Acquisition>, ConfigError> {
    let err = |line: u64, column: Option<&str>, message: String| ConfigError::Parse {
        path: path.into(),
        message: match column {
            Some(c) => format!("line {line}, column `{c}`: {message}"),
            None => format!("line {line}: {message}"),
        },
    };
    // The csv crate's line count skips blank lines, and a record's byte offset is where its
    // parse began (before any blank or comment lines it skipped): count from the first line at
    // or after that offset that holds data. Line starts are indexed once, so each lookup is a
    // binary search plus the lines skipped (linear in the file, not quadratic).
    let starts: Vec<usize> = std::iter::once(0)
        .chain(text.match_indices('\n').map(|(i, _)| i + 1))
        .collect();
    let line_at = |byte: u64| -> u64 {
        let byte = (byte as usize).min(text.len());
        // 0-based index of the line holding `byte`.
        let mut k = starts.partition_point(|&s| s <= byte).saturating_sub(1);
        while k < starts.len() {
            let end = starts.get(k + 1).map_or(text.len(), |&e| e - 1);
            let l = text.get(starts[k]..end.max(starts[k])).unwrap_or("");
            if !l.trim().is_empty() && !l.starts_with('#') {
                break;
            }
            k += 1;
        }
        k as u64 + 1
    };
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let header_line = first_data_line(text);
    let headers = reader
        .headers()
        .map_err(|e| err(header_line, None, e.to_string()))?
        .clone();
    if headers.iter().all(str::is_empty) {
        return Err(err(header_line, None, "empty file: no header".into()));
    }
    let mut cols = std::collections::HashMap::new();
    for (i, h) in headers.iter().enumerate() {
        if !REQUIRED.contains(&h) && !OPTIONAL.contains(&h) {
            return Err(err(
                header_line,
                Some(h),
                format!(
                    "unknown column (known: {}, and optionally {})",
                    REQUIRED.join(","),
                    OPTIONAL.join(",")
                ),
            ));
        }
        if cols.insert(h.to_string(), i).is_some() {
            return Err(err(header_line, Some(h), "column given twice".into()));
        }
    }
    for c in REQUIRED {
        if !cols.contains_key(c) {
            return Err(err(
                header_line,
                None,
                format!("missing column `{c}` (need {})", REQUIRED.join(",")),
            ));
        }
    }
    if cols.contains_key("sza") != cols.contains_key("saa") {
        return Err(err(
            header_line,
            None,
            "columns `sza` and `saa` go together: give both or neither".into(),
        ));
    }
    let mut out = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| {
            let line = e.position().map_or(0, |p| line_at(p.byte()));
            err(line, None, e.to_string())
        })?;
        let line = record.position().map_or(0, |p| line_at(p.byte()));
        let cell = |c: &str| cols.get(c).and_then(|&i| record.get(i)).unwrap_or("");
        let angle = |c: &str, lo: f64, hi: f64| -> Result<Option<f64>, ConfigError> {
            let s = cell(c);
            if s.is_empty() {
                return Ok(None);
            }
            let v: f64 = s
                .parse()
                .map_err(|_| err(line, Some(c), format!("\"{s}\" is not a number")))?;
            if !(lo..=hi).contains(&v) {
                return Err(err(
                    line,
                    Some(c),
                    format!("{v} degrees must lie in [{lo}, {hi}]"),
                ));
            }
            Ok(Some(v))
        };
        let required = |c: &str, v: Option<f64>| {
            v.ok_or_else(|| err(line, Some(c), "is empty (required)".into()))
        };
        let time =
            parse_time(cell("time_utc")).map_err(|e| err(line, Some("time_utc"), e.to_string()))?;
        let srf = cell("srf");
        if srf.is_empty() {
            return Err(err(line, Some("srf"), "is empty (required)".into()));
        }
        let sun = match (angle("sza", 0.0, 180.0)?, angle("saa", -360.0, 360.0)?) {
            (Some(z), Some(a)) => Some((z, a)),
            (None, None) => None,
            (Some(_), None) => {
                return Err(err(line, Some("saa"), "is empty but `sza` is given".into()))
            }
            (None, Some(_)) => {
                return Err(err(line, Some("sza"), "is empty but `saa` is given".into()))
            }
        };
        out.push(Acquisition {
            time_utc: format_utc(&time),
            vza: required("vza", angle("vza", 0.0, 90.0)?)?,
            vaa: required("vaa", angle("vaa", -360.0, 360.0)?)?,
            srf: srf.to_string(),
            sun,
        });
    }
    if out.is_empty() {
        return Err(err(header_line + 1, None, "no acquisitions".into()));
    }
    Ok(out)
}

/// The 1-based line of the header: the first line that is neither blank nor a comment.
fn first_data_line(text: &str) -> u64 {
    text.lines()
        .position(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .map_or(1, |i| i as u64 + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vec<Acquisition>, String> {
        parse_acquisitions(text, Path::new("acq.csv")).map_err(|e| e.to_string())
    }

    #[test]
    fn reads_rows_and_normalises_offsets_to_utc() {
        let a = parse(
            "# a comment\ntime_utc, vza, vaa, srf\n\
             2026-01-15T09:45:00Z,5.2,103.0,sentinel_2a-msi-4\n\
             2026-01-15T11:45:00+02:00,5.2,103.0,\"my srf.csv\"\n\
             2026-01-15T09:45:00.5-00:30,0,0,x\n",
        )
        .unwrap();
        assert_eq!(a.len(), 3);
        assert_eq!(a[0].time_utc, "2026-01-15T09:45:00Z");
        assert_eq!(a[1].time_utc, "2026-01-15T09:45:00Z");
        assert_eq!(a[1].srf, "my srf.csv");
        assert_eq!(a[2].time_utc, "2026-01-15T10:15:00.500Z");
        assert!(a.iter().all(|x| x.sun.is_none()));
    }

    #[test]
    fn sun_columns_override_per_row() {
        let a = parse(
            "time_utc,vza,vaa,srf,sza,saa\n\
             2026-01-15T09:45:00Z,5,103,b4,30.5,140\n\
             2026-01-15T09:45:00Z,5,103,b4,,\n",
        )
        .unwrap();
        assert_eq!(a[0].sun, Some((30.5, 140.0)));
        assert_eq!(a[1].sun, None);
    }

    #[test]
    fn errors_name_file_line_and_column() {
        let cases = [
            ("time_utc,vza,vaa,srf,sun_zenith\n", "`sun_zenith`", "line 1"),
            (
                "time_utc,vza,vaa,srf\n2026-01-15T09:45:00Z,5,1,b\n2026-01-15T09:45:00,5,1,b\n",
                "`time_utc`",
                "line 3",
            ),
            ("time_utc,vza,vaa,srf\n\n2026-01-15T09:45:00Z,95,1,b\n", "`vza`", "line 3"),
            (
                "time_utc,vza,vaa,srf\n# c\n\n# d\n2026-01-15T09:45:00Z,1,1,b\n2026-01-15T09:45:00Z,1,-400,b\n",
                "`vaa`",
                "line 6",
            ),
            ("time_utc,vza,vaa,srf\n2026-01-15T09:45:00Z,abc,1,b\n", "`vza`", "line 2"),
            ("time_utc,vza,vaa,srf\n2026-01-15T09:45:00Z,1,1,\n", "`srf`", "line 2"),
            (
                "time_utc,vza,vaa,srf,sza,saa\n2026-01-15T09:45:00Z,1,1,b,190,3\n",
                "`sza`",
                "line 2",
            ),
            (
                "time_utc,vza,vaa,srf,sza,saa\n2026-01-15T09:45:00Z,1,1,b,10,\n",
                "`saa`",
                "line 2",
            ),
            (
                "time_utc,vza,vaa,srf,sza,saa\n2026-01-15T09:45:00Z,1,1,b,10,nan\n",
                "`saa`",
                "line 2",
            ),
            ("time_utc,vza,vaa,srf,sza\n", "`saa`", "line 1"),
            ("time_utc,vza,srf\n", "`vaa`", "line 1"),
            ("time_utc,vza,vaa,srf,vza\n", "`vza`", "line 1"),
            ("time_utc,vza,vaa,srf\n", "no acquisitions", "line 2"),
            ("time_utc,vza,vaa,srf\n2026-01-15T09:45:00Z,1,1\n", "", "line 2"),
        ];
        for (text, what, line) in cases {
            let e = parse(text).unwrap_err();
            assert!(
                e.contains("acq.csv") && e.contains(what) && e.contains(line),
                "{text:?}: {e}"
            );
        }
    }

    /// Rationale: line numbers of errors come from an index of line starts, so a long file is
    /// read in linear time (the former per-record count from the file's start took minutes at
    /// 10⁵ rows) and the bad row is still named exactly, after blank and comment lines.
    #[test]
    fn long_files_name_the_bad_last_row() {
        let mut text = String::from("time_utc,vza,vaa,srf\n# comment\n\n");
        for _ in 0..100_000 {
            text.push_str("2026-01-15T09:45:00Z,5,103,b4\n");
        }
        text.push_str("\n# last\n2026-01-15T09:45:00Z,5,999,b4\n");
        let e = parse(&text).unwrap_err();
        assert!(e.contains("line 100006") && e.contains("`vaa`"), "{e}");
        text.truncate(text.rfind("2026").unwrap());
        assert_eq!(parse(&text).unwrap().len(), 100_000);
    }
}
