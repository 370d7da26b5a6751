//! The envelope study's results as Markdown tables and as CSV.

use super::{
    Cell, CellStats, EnvelopeResults, PassSchedule, RunSetting, ValidVector, FIELDS_PER_RECORDING,
    FLOW_ANGLE_DEG, GROSS_ABSOLUTE, GROSS_RELATIVE, PARTICLE_DIAMETER_PX, SENSOR_PRESET,
};
use std::fmt::Write;

impl EnvelopeResults {
    /// The report: what was simulated, then one table per method and pass schedule with a
    /// row per speed and density and a column per window and slab, each cell "RMS error
    /// (px/ms) / valid % / gross %", failing cells in bold; the settings the library
    /// rejected under each table; and the count of failing cells.
    pub fn markdown(&self) -> String {
        let spec = &self.spec;
        let mut out = String::new();
        let seeds: Vec<String> = spec.seeds.iter().map(u64::to_string).collect();
        let _ = writeln!(
            out,
            "Uniform flows at {FLOW_ANGLE_DEG}° from +x on {size}×{size} px, `{SENSOR_PRESET}` sensor, particle images {PARTICLE_DIAMETER_PX} px; \
             seeds {seeds}; {FIELDS_PER_RECORDING} fields per recording of {duration} ms; windows at 50 % overlap, every other setting at its default.",
            size = spec.size,
            seeds = seeds.join(", "),
            duration = spec.duration_us() / 1000,
        );
        let _ = writeln!(
            out,
            "Each cell: RMS error of the valid vectors (px/ms) / valid vectors (%) / gross errors (% of the valid vectors off by more than \
             max({GROSS_ABSOLUTE} px/ms, {} % of |v|)); **bold**: the cell fails (gross ≥ 1 %); n/a: the library rejects the setting (reason below the table).",
            GROSS_RELATIVE * 100.0
        );
        let mut tallies = Vec::new();
        for method in &spec.methods {
            for &passes in &spec.passes {
                let columns: Vec<RunSetting> = spec
                    .settings()
                    .into_iter()
                    .filter(|s| &s.method == method && s.passes == passes)
                    .collect();
                tallies.push(self.table(&mut out, method, passes, &columns));
            }
        }
        let measured: usize = tallies.iter().map(|t| t.1).sum();
        let failing: usize = tallies.iter().map(|t| t.2).sum();
        let not_applicable = self.cells.len() - measured;
        let each: Vec<String> = tallies
            .iter()
            .map(|(name, _, fails)| format!("{name} {fails}"))
            .collect();
        let _ = writeln!(
            out,
            "\ncells failing: {failing} of {measured} measured ({}), {not_applicable} n/a",
            each.join(", ")
        );
        out
    }

    /// Write one table into `out`; returns its name, its measured cells and its failing ones.
    fn table(
        &self,
        out: &mut String,
        method: &str,
        passes: PassSchedule,
        columns: &[RunSetting],
    ) -> (String, usize, usize) {
        let schedule = match passes {
            PassSchedule::Single => "single pass (W)".to_string(),
            PassSchedule::Default => "default passes (2W → W, last pass repeated)".to_string(),
        };
        let _ = writeln!(out, "\n**{method}, {schedule}**\n");
        let _ = write!(out, "| v px/ms | particles/px |");
        for c in columns {
            let _ = write!(out, " W {}, T {} |", c.window, c.slab);
        }
        let _ = write!(out, "\n|---:|---:|");
        for _ in columns {
            let _ = write!(out, "---|");
        }
        out.push('\n');
        let (mut measured, mut failing) = (0, 0);
        let mut rejected: Vec<(String, Vec<String>)> = Vec::new();
        for &speed in &self.spec.speeds {
            for &density in &self.spec.densities {
                let _ = write!(out, "| {speed} | {density} |");
                for c in columns {
                    let cell = self.cell(speed, density, c);
                    let text = match cell.map(|c| &c.outcome) {
                        Some(Ok(stats)) => {
                            measured += 1;
                            failing += usize::from(stats.fails());
                            cell_text(stats)
                        }
                        Some(Err(reason)) => {
                            let column = format!("W {}, T {}", c.window, c.slab);
                            match rejected.iter_mut().find(|r| &r.0 == reason) {
                                Some(r) if !r.1.contains(&column) => r.1.push(column),
                                Some(_) => {}
                                None => rejected.push((reason.clone(), vec![column])),
                            }
                            "n/a".to_string()
                        }
                        None => String::new(),
                    };
                    let _ = write!(out, " {text} |");
                }
                out.push('\n');
            }
        }
        let name = format!("{method} {passes}");
        let _ = writeln!(out, "\n{name}: {failing} of {measured} cells fail.");
        for (reason, columns) in rejected {
            let _ = writeln!(out, "n/a ({}): {reason}", columns.join("; "));
        }
        (name, measured, failing)
    }

    /// Every cell as a CSV row, with a header: the setting, the speed and density, the counts
    /// and errors (px/ms), whether it fails, the processing time (s), and for cells that did
    /// not run the library's reason (`note`; the other values empty).
    pub fn csv(&self) -> String {
        let mut out = String::from(
            "method,passes,window_px,slab,speed_px_per_ms,density_per_px,recordings,fields,vectors,valid,valid_share,\
             rms_px_per_ms,rms_relative,bias_u_px_per_ms,bias_v_px_per_ms,gross,gross_share,fails,seconds,note\n",
        );
        for Cell {
            speed,
            density,
            setting: s,
            outcome,
        } in &self.cells
        {
            let _ = write!(
                out,
                "{},{},{},{},{speed},{density},",
                s.method, s.passes, s.window, s.slab
            );
            match outcome {
                Ok(c) => {
                    let _ = writeln!(
                        out,
                        "{},{},{},{},{},{},{},{},{},{},{},{},{:.3},",
                        c.recordings,
                        c.fields,
                        c.vectors,
                        c.valid,
                        number(c.valid_share()),
                        number(c.rms),
                        number(c.rms / speed),
                        number(c.bias[0]),
                        number(c.bias[1]),
                        c.gross,
                        number(c.gross_share()),
                        c.fails(),
                        c.seconds
                    );
                }
                Err(reason) => {
                    let _ = writeln!(
                        out,
                        ",,,,,,,,,,,,,\"{}\"",
                        reason.replace('"', "\"\"").replace('\n', " ")
                    );
                }
            }
        }
        out
    }
}

/// `0.0123 / 99.6 / 0.00`, bold when the cell fails; `— / 0.0 / —` without valid vectors.
fn cell_text(c: &CellStats) -> String {
    if c.valid == 0 {
        return "— / 0.0 / —".to_string();
    }
    let text = format!(
        "{} / {:.1} / {:.2}",
        rms_text(c.rms),
        100.0 * c.valid_share(),
        100.0 * c.gross_share()
    );
    if c.fails() {
        format!("**{text}**")
    } else {
        text
    }
}

/// An RMS error with about three significant digits.
fn rms_text(rms: f64) -> String {
    match rms {
        r if r >= 10.0 => format!("{r:.1}"),
        r if r >= 1.0 => format!("{r:.2}"),
        r if r >= 0.1 => format!("{r:.3}"),
        r => format!("{r:.4}"),
    }
}

/// A CSV number: empty when not defined.
impl ValidVector {
    /// The header of [`ValidVector::csv_row`], with its line end.
    pub const CSV_HEADER: &'static str =
        "method,passes,window_px,slab,speed_px_per_ms,density_per_px,seed,t_us,x_px,y_px,\
         u_px_per_ms,v_px_per_ms,peak,peak_ratio,event_count,slab_us,displacement_px,\
         error_px_per_ms,gross\n";

    /// The vector as one CSV line, with its line end: its cell, seed, field time and
    /// position, velocity, evidence, claimed displacement, error and whether it is gross.
    pub fn csv_row(&self) -> String {
        let s = &self.setting;
        format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            s.method,
            s.passes,
            s.window,
            s.slab,
            self.speed,
            self.density,
            self.seed,
            self.t_us,
            self.x,
            self.y,
            number(self.u),
            number(self.v),
            number(f64::from(self.peak)),
            number(f64::from(self.peak_ratio)),
            self.event_count,
            self.slab_us,
            number(self.displacement_px),
            number(self.error),
            self.gross
        )
    }
}

fn number(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.6}")
    } else {
        String::new()
    }
}
