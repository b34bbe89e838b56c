//! Counts and timings of a render, per stage, for the summary line and the benchmarks.

use std::time::Duration;

/// What a render did.
#[derive(Clone, Debug, Default)]
pub struct RenderStats {
    /// Wall time of the whole render (without scene loading and output).
    pub wall_time: Duration,
    /// Time spent in each stage: generate, intersect, shade, shadow, film (compaction).
    pub stage_time: [Duration; 5],
    /// Camera rays traced.
    pub camera_rays: u64,
    /// Bounce rays traced (closest-hit rays after the camera rays).
    pub bounce_rays: u64,
    /// Shadow rays traced.
    pub shadow_rays: u64,
    /// Rays of the light paths for caustics (their bounces and camera connections).
    pub light_rays: u64,
    /// Wall time of the light paths for caustics.
    pub light_time: Duration,
    /// Paths completed (samples).
    pub samples: u64,
    /// Paths cut by the depth cap.
    pub capped_paths: u64,
    /// Samples discarded because they were NaN or infinite.
    pub rejected_samples: u64,
    /// Samples per pixel completed by every pixel.
    pub complete_spp: u32,
    /// Whether the render stopped before all samples were taken.
    pub interrupted: bool,
    /// Whether sampling was adaptive (the summary then reports the spread of samples).
    pub adaptive: bool,
    /// Fewest samples any pixel holds.
    pub spp_min: u32,
    /// Mean samples per pixel.
    pub spp_mean: f64,
    /// Most samples any pixel holds.
    pub spp_max: u32,
}

/// Names of the stages in [`RenderStats::stage_time`] order.
pub const STAGE_NAMES: [&str; 5] = ["generate", "intersect", "shade", "shadow", "film"];

impl RenderStats {
    /// The counts and stage times of two parts of a render added up (for batches traced in
    /// parallel; the stage times become CPU time).
    pub fn merged(self, other: RenderStats) -> RenderStats {
        let mut sum = self;
        for (t, o) in sum.stage_time.iter_mut().zip(other.stage_time) {
            *t += o;
        }
        sum.camera_rays += other.camera_rays;
        sum.bounce_rays += other.bounce_rays;
        sum.shadow_rays += other.shadow_rays;
        sum.light_rays += other.light_rays;
        sum.light_time += other.light_time;
        sum.samples += other.samples;
        sum.capped_paths += other.capped_paths;
        sum.rejected_samples += other.rejected_samples;
        sum
    }

    /// All rays traced.
    pub fn total_rays(&self) -> u64 {
        self.camera_rays + self.bounce_rays + self.shadow_rays + self.light_rays
    }

    /// One line: wall time, samples/s, rays/s, rays per kind and the share of time per stage.
    pub fn summary(&self) -> String {
        let secs = self.wall_time.as_secs_f64().max(1e-9);
        let stage_total: f64 = self
            .stage_time
            .iter()
            .map(Duration::as_secs_f64)
            .sum::<f64>()
            .max(1e-12);
        let shares: Vec<String> = STAGE_NAMES
            .iter()
            .zip(&self.stage_time)
            .map(|(n, t)| format!("{n} {:.0}%", 100.0 * t.as_secs_f64() / stage_total))
            .collect();
        let mut line = format!(
            "{:.2} s, {} samples ({:.2} M samples/s), {:.1} M rays/s (camera {}, bounce {}, shadow {}); time: {}",
            secs,
            self.samples,
            self.samples as f64 / secs / 1e6,
            self.total_rays() as f64 / secs / 1e6,
            self.camera_rays,
            self.bounce_rays,
            self.shadow_rays,
            shares.join(", ")
        );
        if self.adaptive {
            line += &format!(
                "; adaptive: spp min {}, mean {:.1}, max {}",
                self.spp_min, self.spp_mean, self.spp_max
            );
        }
        if self.light_rays > 0 {
            line += &format!(
                "; caustic light paths: {} rays in {:.2} s",
                self.light_rays,
                self.light_time.as_secs_f64()
            );
        }
        if self.capped_paths > 0 {
            line += &format!("; {} paths cut at the depth cap", self.capped_paths);
        }
        if self.rejected_samples > 0 {
            line += &format!("; {} NaN/infinite samples discarded", self.rejected_samples);
        }
        line
    }
}
