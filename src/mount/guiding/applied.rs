//! The applied correction C: everything the RA axis did beyond sidereal
//! tracking, from the steps actually emitted, and the gear time.

/// Signed difference a - b of two microsecond times, in seconds.
pub(super) fn secs_between(a: u64, b: u64) -> f64 {
    if a >= b {
        (a - b) as f64 * 1e-6
    } else {
        -((b - a) as f64 * 1e-6)
    }
}

/// The state of C at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Mark {
    pub at_us: u64,
    pub gear_s: f64,
    /// C at the instant, arcsec.
    pub c: f64,
    /// Integral of C over wall time since the origin, arcsec s.
    pub integral: f64,
    /// Wall time the command port has moved the RA axis or stopped its
    /// tracking, since the origin, microseconds: a frame whose interval
    /// holds some measured nothing of the gear.
    pub port_us: u64,
}

/// C and its integral, updated at every `Guiding::rates` call.
pub(super) struct Applied {
    sidereal_sps: f64,
    arcsec_per_step: f64,
    /// Wall time and step count of the first update.
    origin: Option<(u64, i64)>,
    last_us: u64,
    last_steps: i64,
    last_c: f64,
    integral: f64,
    /// The RA rate set at the last update, steps/s.
    last_ra_sps: f32,
    /// Sum of the dithers' moves and of the excluded motion (below),
    /// arcsec, taken out of C.
    dither_offset: f64,
    /// The part of the RA rate set at the last update that is no gear
    /// correction (manual motion, tracking off), steps/s: the model must
    /// not learn it, so it is taken out of C as it is made.
    excluded_sps: f32,
    /// The command port moves the RA axis or has stopped its tracking
    /// (since the last update), and for how long in all ([`Mark::port_us`]).
    port_motion: bool,
    port_us: u64,
}

impl Applied {
    pub fn new(sidereal_sps: f64, arcsec_per_step: f64) -> Self {
        Applied {
            sidereal_sps,
            arcsec_per_step,
            origin: None,
            last_us: 0,
            last_steps: 0,
            last_c: 0.0,
            integral: 0.0,
            last_ra_sps: 0.0,
            dither_offset: 0.0,
            excluded_sps: 0.0,
            port_motion: false,
            port_us: 0,
        }
    }

    pub fn sidereal_sps(&self) -> f64 {
        self.sidereal_sps
    }

    pub fn arcsec_per_step(&self) -> f64 {
        self.arcsec_per_step
    }

    pub fn started(&self) -> bool {
        self.origin.is_some()
    }

    pub fn last_us(&self) -> u64 {
        self.last_us
    }

    /// C at the last update, arcsec.
    pub fn c(&self) -> f64 {
        self.last_c
    }

    /// Gear time at the last update (seconds).
    pub fn gear_time_s(&self) -> f64 {
        self.last_steps as f64 / self.sidereal_sps
    }

    /// A dither moved the mount by `arcsec`: no gear error.
    pub fn add_dither(&mut self, arcsec: f64) {
        self.dither_offset += arcsec;
    }

    /// C, its integral and the gear time at `at_us`, extrapolated from the
    /// last update with the rate set then (exact between updates).
    pub fn mark_at(&self, at_us: u64) -> Mark {
        if self.origin.is_none() {
            return Mark {
                at_us,
                gear_s: 0.0,
                c: 0.0,
                integral: 0.0,
                port_us: 0,
            };
        }
        let dt = secs_between(at_us, self.last_us);
        let extra_sps = self.last_ra_sps as f64 - self.excluded_sps as f64 - self.sidereal_sps;
        let c = self.last_c + extra_sps * self.arcsec_per_step * dt;
        Mark {
            at_us,
            gear_s: (self.last_steps as f64 + self.last_ra_sps as f64 * dt) / self.sidereal_sps,
            c,
            integral: self.integral + 0.5 * (self.last_c + c) * dt,
            port_us: self.port_us_at(at_us),
        }
    }

    fn port_us_at(&self, at_us: u64) -> u64 {
        match self.port_motion {
            true => self.port_us + at_us.saturating_sub(self.last_us),
            false => self.port_us,
        }
    }

    /// The first update: the origin of C.
    pub fn start(&mut self, now_us: u64, ra_steps: i64) {
        self.origin = Some((now_us, ra_steps));
        self.last_us = now_us;
        self.last_steps = ra_steps;
        self.last_c = -self.dither_offset;
    }

    /// An update whose time went backwards: only the step count is taken.
    pub fn take_steps(&mut self, ra_steps: i64) {
        self.last_steps = ra_steps;
    }

    /// An update at `now_us` (not before the last) with the RA step count.
    pub fn advance(&mut self, now_us: u64, ra_steps: i64) {
        let Some((t0, s0)) = self.origin else {
            return self.start(now_us, ra_steps);
        };
        let dt = secs_between(now_us, self.last_us);
        // Adds exactly 0.0 (C unchanged) unless motion was excluded.
        self.dither_offset += self.excluded_sps as f64 * dt * self.arcsec_per_step;
        let not_tracking =
            ra_steps.wrapping_sub(s0) as f64 - self.sidereal_sps * secs_between(now_us, t0);
        let c = not_tracking * self.arcsec_per_step - self.dither_offset;
        self.integral += 0.5 * (self.last_c + c) * dt;
        self.last_c = c;
        self.port_us = self.port_us_at(now_us);
        self.last_us = now_us;
        self.last_steps = ra_steps;
    }

    /// The RA rate set from now on, steps/s, the part of it that is no
    /// gear correction, and whether the command port moves the axis (or
    /// has stopped its tracking).
    pub fn set_ra_rate(&mut self, sps: f32, excluded_sps: f32, port_motion: bool) {
        self.last_ra_sps = sps;
        self.excluded_sps = excluded_sps;
        self.port_motion = port_motion;
    }
}
