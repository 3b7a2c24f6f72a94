//! Civil UTC date and time of a Unix time, for the timestamps truepos writes (audit trail, report
//! header, protocol logs): one definition of the calendar arithmetic, no clock and no I/O here.
//!
//! Entry points: [`UtcDateTime::from_unix`], [`UtcDateTime::iso8601_millis`]
//! (`2026-11-24T01:02:03.456Z`), [`UtcDateTime::human`] (`2026-11-24 01:02:03 UTC`).

/// A UTC calendar date and time (proleptic Gregorian calendar, no leap seconds, as Unix time).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UtcDateTime {
    /// Calendar year, proleptic Gregorian (year 0 is 1 BC).
    pub year: i64,
    /// Month, 1 to 12.
    pub month: u32,
    /// Day of the month, 1 to 31.
    pub day: u32,
    /// Hour, 0 to 23.
    pub hour: u32,
    /// Minute, 0 to 59.
    pub minute: u32,
    /// Second, 0 to 59 (no leap seconds).
    pub second: u32,
}

impl UtcDateTime {
    /// The civil date and time of `secs` seconds since 1970-01-01T00:00:00Z (negative before it).
    /// Days to civil date by the era algorithm (400-year eras of 146 097 days; H. Hinnant,
    /// "chrono-Compatible Low-Level Date Algorithms").
    pub fn from_unix(secs: i64) -> Self {
        let days = secs.div_euclid(86_400);
        let sod = secs.rem_euclid(86_400);
        let z = days + 719_468;
        let era = z.div_euclid(146_097);
        let doe = z - era * 146_097;
        let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
        let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
        let mp = (5 * doy + 2) / 153;
        let day = doy - (153 * mp + 2) / 5 + 1;
        let month = if mp < 10 { mp + 3 } else { mp - 9 };
        let year = yoe + era * 400 + i64::from(month <= 2);
        // All of these are in range by construction (sod < 86 400, 1 ≤ month ≤ 12, 1 ≤ day ≤ 31).
        Self {
            year,
            month: month as u32,
            day: day as u32,
            hour: (sod / 3600) as u32,
            minute: (sod % 3600 / 60) as u32,
            second: (sod % 60) as u32,
        }
    }

    /// ISO 8601 UTC with milliseconds: `YYYY-MM-DDThh:mm:ss.fffZ`.
    pub fn iso8601_millis(&self, millis: u32) -> String {
        format!(
            "{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:03}Z",
            self.year,
            self.month,
            self.day,
            self.hour,
            self.minute,
            self.second,
            millis.min(999)
        )
    }

    /// For people: `YYYY-MM-DD hh:mm:ss UTC`.
    pub fn human(&self) -> String {
        format!(
            "{:04}-{:02}-{:02} {:02}:{:02}:{:02} UTC",
            self.year, self.month, self.day, self.hour, self.minute, self.second
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Known instants (epoch, a leap day, a recent date, before the epoch) and a brute-force walk
    /// over 800 years of days against a day-by-day calendar count.
    #[test]
    fn civil_dates_of_known_instants_and_every_day_of_800_years() {
        let f = |s| UtcDateTime::from_unix(s).iso8601_millis(0);
        assert_eq!(f(0), "1970-01-01T00:00:00.000Z");
        assert_eq!(f(951_782_400), "2000-02-29T00:00:00.000Z");
        assert_eq!(f(1_700_000_000), "2023-11-14T22:13:20.000Z");
        assert_eq!(f(-1), "1969-12-31T23:59:59.000Z");
        assert_eq!(UtcDateTime::from_unix(-1).human(), "1969-12-31 23:59:59 UTC");
        let leap = |y: i64| (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
        let (mut y, mut m, mut d) = (1800_i64, 1_u32, 1_u32);
        let start = -(170 * 365 + 41) as i64; // days from 1800-01-01 to 1970-01-01: 62 091
        assert_eq!(start, -62_091);
        for day in start..start + 800 * 366 {
            let t = UtcDateTime::from_unix(day * 86_400 + 3_723);
            assert_eq!((t.year, t.month, t.day, t.hour, t.minute, t.second), (y, m, d, 1, 2, 3));
            let len = match m {
                2 if leap(y) => 29,
                2 => 28,
                4 | 6 | 9 | 11 => 30,
                _ => 31,
            };
            d += 1;
            if d > len {
                d = 1;
                m += 1;
                if m > 12 {
                    m = 1;
                    y += 1;
                }
            }
        }
    }
}
