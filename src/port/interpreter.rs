//! The command interpreter of one port, sans-IO: bytes in, replies out to a
//! [`ReplySink`], actions to the mount through [`MountPort`]. The transport
//! (USB CDC, UART, a pty in the simulator) calls [`Interpreter::feed`] with
//! whatever it received and the time; nothing here blocks, allocates or
//! keeps more than the fixed state below.

use super::command::{parse, Command, Own, Query, Refusal, Setting, SlewRate};
use super::coords::{Equatorial, Precision};
use super::lexer::{Lexer, LexerCounters, Token};
use super::mount_port::{Axis, GuidePulse, MountPort, PecState};
use super::own;
use super::reply::{Reply, ReplySink};
use super::site::Site;
use super::telemetry::{self, TelemetryFrame};
use super::PortCounters;

/// How long a save's reply waits for the store's outcome. A save reads
/// both pages twice and may erase a sector (1-2 s); beyond this the store
/// is taken to have failed and the client hears `0`.
pub const STORE_REPLY_TIMEOUT_US: u64 = 20_000_000;

/// The interpreter's state besides the lexer: what the client chose.
#[derive(Clone, Debug)]
struct Session {
    precision: Precision,
    rate: SlewRate,
    /// Where `:Sr#` and `:Sd#` said to sync to.
    target: Equatorial,
    site: Site,
    telemetry: bool,
    /// A save asked on this port whose reply waits for the store's
    /// outcome ([`Interpreter::store_done`]), until this time.
    store_reply_due_us: Option<u64>,
    /// The counters the lexer does not keep.
    counters: PortCounters,
}

/// One port's interpreter: 184 bytes on x86-64, its lexer's buffer
/// included (the unit test `size` bounds it at 192).
#[derive(Clone, Debug)]
pub struct Interpreter {
    lexer: Lexer,
    session: Session,
}

impl Default for Interpreter {
    fn default() -> Self {
        Self::new()
    }
}

impl Interpreter {
    /// High precision (`:U#` switches), the guide rate selected (the
    /// slowest: a `:Mn#` before any `:R?#` is a guide pulse), telemetry off.
    pub fn new() -> Self {
        Interpreter {
            lexer: Lexer::new(),
            session: Session {
                precision: Precision::High,
                rate: SlewRate::Guide,
                target: Equatorial::default(),
                site: Site::default(),
                telemetry: false,
                store_reply_due_us: None,
                counters: PortCounters::default(),
            },
        }
    }

    /// Takes the bytes received at `now_us` (microseconds, the board's
    /// clock), carries out every command they complete and sends each reply
    /// to `out`. Empty `bytes` only let a stale half command time out.
    pub fn feed(
        &mut self,
        bytes: &[u8],
        now_us: u64,
        mount: &mut impl MountPort,
        out: &mut impl ReplySink,
    ) {
        self.lexer.expire(now_us);
        if self
            .session
            .store_reply_due_us
            .is_some_and(|due| now_us >= due)
        {
            self.session.store_reply_due_us = None;
            self.session.counters.store_timeouts =
                self.session.counters.store_timeouts.wrapping_add(1);
            self.session.sent(out.send(b"0"));
        }
        for &byte in bytes {
            // Before the byte: a command's `#` changes no lexer counter, and
            // the frame borrows the lexer.
            let lexer_counters = self.lexer.counters();
            match self.lexer.push(byte, now_us) {
                None => {}
                Some(Token::Ack) => {
                    // Polar: an equatorial mount (Meade's `A` is alt-az).
                    self.session.sent(out.send(b"P"));
                    self.session.counters.acks = self.session.counters.acks.wrapping_add(1);
                }
                Some(Token::Command(body)) => {
                    let port = self.session.counters_now(lexer_counters);
                    self.session.execute(body, now_us, port, mount, out)
                }
            }
        }
    }

    pub fn counters(&self) -> PortCounters {
        self.session.counters_now(self.lexer.counters())
    }

    /// The store's outcome of the save this port asked for: `1` saved (read
    /// back as written), `0` not. Ignored if no save is waiting (its reply
    /// timed out).
    pub fn store_done(&mut self, saved: bool, out: &mut impl ReplySink) {
        if self.session.store_reply_due_us.take().is_some() {
            self.session.sent(out.send(if saved { b"1" } else { b"0" }));
        }
    }

    /// Whether a save asked on this port waits for the store's outcome.
    pub fn awaits_store(&self) -> bool {
        self.session.store_reply_due_us.is_some()
    }

    /// Whether this port's client asked for telemetry (`:~T1#`).
    pub fn telemetry(&self) -> bool {
        self.session.telemetry
    }

    /// Sends a guide frame's telemetry line, if this port's client asked.
    pub fn send_telemetry(&mut self, frame: &TelemetryFrame, out: &mut impl ReplySink) {
        if self.session.telemetry {
            let mut line = Reply::new();
            telemetry::write(frame, &mut line);
            self.session.sent(out.send(line.as_bytes()));
        }
    }
}

impl Session {
    /// Counts a reply the transport dropped.
    fn sent(&mut self, taken: bool) {
        if !taken {
            self.counters.replies_dropped = self.counters.replies_dropped.wrapping_add(1);
        }
    }
    /// The port's counters, the lexer's included.
    fn counters_now(&self, lexer: LexerCounters) -> PortCounters {
        PortCounters {
            garbage_bytes: lexer.garbage_bytes,
            overflows: lexer.overflows,
            timeouts: lexer.timeouts,
            ..self.counters
        }
    }

    fn execute(
        &mut self,
        body: &[u8],
        now_us: u64,
        port: PortCounters,
        mount: &mut impl MountPort,
        out: &mut impl ReplySink,
    ) {
        let mut reply = Reply::new();
        match parse(body) {
            Ok(command) => {
                self.counters.commands = self.counters.commands.wrapping_add(1);
                self.carry_out(command, now_us, port, mount, &mut reply);
            }
            Err(Refusal::Unknown) => {
                self.counters.unknown = self.counters.unknown.wrapping_add(1);
            }
            Err(Refusal::BadValue) => {
                self.counters.bad_values = self.counters.bad_values.wrapping_add(1);
            }
            Err(Refusal::BadSetting) => {
                self.counters.bad_values = self.counters.bad_values.wrapping_add(1);
                reply.byte(b'0');
            }
        }
        if reply.overflowed() {
            self.counters.replies_cut = self.counters.replies_cut.wrapping_add(1);
        }
        if !reply.is_empty() {
            self.sent(out.send(reply.as_bytes()));
        }
    }

    fn carry_out(
        &mut self,
        command: Command,
        now_us: u64,
        port: PortCounters,
        mount: &mut impl MountPort,
        reply: &mut Reply,
    ) {
        match command {
            Command::Get(query) => {
                self.answer(query, now_us, mount, reply);
                reply.byte(b'#');
            }
            Command::Set(setting) => self.set(setting, now_us, reply),
            Command::TogglePrecision => self.precision = self.precision.toggled(),
            Command::Sync => {
                mount.sync(self.target);
                // Any `...#` will do for the clients; OnStep's.
                reply.text(b"N/A#");
            }
            // `1` + a message is the "not possible" the clients understand.
            Command::Goto => {
                reply.text(b"1No goto on this mount#");
            }
            // Not slewing: no bars.
            Command::DistanceBars => {
                reply.byte(b'#');
            }
            Command::Guide(pulse) => mount.guide(pulse),
            Command::SelectRate(rate) => self.rate = rate,
            Command::Move(line) => match self.rate {
                // No duration: until its `:Q?#`, at most the longest pulse.
                SlewRate::Guide => mount.guide(GuidePulse::longest(line)),
                SlewRate::Manual(rate) => mount.move_at(line, rate),
            },
            Command::Stop(axis) => mount.stop(axis),
            Command::StopAll => {
                mount.stop(Axis::Ra);
                mount.stop(Axis::Dec);
            }
            Command::Tracking(on) => {
                mount.set_tracking(on);
                reply.byte(b'1');
            }
            // No reply: INDI's LX200 driver reads none after `:hP#`.
            Command::Park => mount.park(),
            Command::Unpark => mount.unpark(),
            Command::Own(Own::ConfigSave) => self.ask_store(now_us, reply, || mount.save_config()),
            Command::Own(Own::SaveModel) => self.ask_store(now_us, reply, || mount.save_model()),
            Command::Own(command) => {
                if let Some(on) = own::answer(command, now_us, port, mount, reply) {
                    self.telemetry = on;
                }
            }
        }
    }

    /// A save: asked of the mount unless one asked on this port still waits
    /// (one at a time, so that each outcome answers its own command). The
    /// reply waits for the outcome; `0` now if nothing was asked.
    fn ask_store(&mut self, now_us: u64, reply: &mut Reply, ask: impl FnOnce() -> bool) {
        if self.store_reply_due_us.is_none() && ask() {
            self.store_reply_due_us = Some(now_us.saturating_add(STORE_REPLY_TIMEOUT_US));
        } else {
            reply.byte(b'0');
        }
    }

    /// The answer to a query, without its `#`.
    fn answer(&self, query: Query, now_us: u64, mount: &mut impl MountPort, reply: &mut Reply) {
        match query {
            Query::Ra => mount.position().ra.write(self.precision, reply),
            Query::Dec => mount.position().dec.write(self.precision, reply),
            Query::ClockFormat => {
                reply.text(b"24");
            }
            Query::SiteName => {
                reply.text(b"Site");
            }
            // Sidereal, as a 60 Hz synchronous motor's frequency (60.164 Hz).
            Query::TrackingRate => {
                reply.text(if mount.status().tracking {
                    b"60.1"
                } else {
                    b"00.0"
                });
            }
            Query::Latitude => self.site.latitude.write(reply),
            Query::Longitude => self.site.longitude.write(reply),
            Query::UtcOffset => self.site.utc_offset.write(reply),
            Query::LocalTime => self.site.time(now_us).write(reply),
            Query::Date => self.site.date.write(reply),
            Query::Status => status_flags(mount, reply),
            Query::Product => {
                reply.text(mount.identity().product.as_bytes());
            }
            Query::Version => {
                reply.text(mount.identity().version.as_bytes());
            }
            Query::BuildDate => {
                reply.text(mount.identity().date.as_bytes());
            }
            Query::BuildTime => {
                reply.text(mount.identity().time.as_bytes());
            }
        }
    }

    fn set(&mut self, setting: Setting, now_us: u64, reply: &mut Reply) {
        match setting {
            Setting::TargetRa(ra) => self.target.ra = ra,
            Setting::TargetDec(dec) => self.target.dec = dec,
            Setting::UtcOffset(offset) => self.site.utc_offset = offset,
            Setting::Latitude(latitude) => self.site.latitude = latitude,
            Setting::Longitude(longitude) => self.site.longitude = longitude,
            Setting::LocalTime(time) => self.site.set_time(time, now_us),
            Setting::Date(date) => {
                self.site.date = date;
                // Meade's handbox answers a date with two lines after the
                // `1`, and the clients read both.
                reply.text(b"1Updating Planetary Data#                              #");
                return;
            }
        }
        reply.byte(b'1');
    }
}

/// OnStep's `:GU#` flags where they apply: `n` not tracking, `N` no goto
/// under way (always), `p` not parked or `P` parked, `G` a guide pulse
/// running, then the PEC state (`/` off, `^` learning, `~` playing).
fn status_flags(mount: &mut impl MountPort, reply: &mut Reply) {
    let status = mount.status();
    if !status.tracking {
        reply.byte(b'n');
    }
    reply.byte(b'N');
    reply.byte(if status.parked { b'P' } else { b'p' });
    if status.guiding {
        reply.byte(b'G');
    }
    reply.byte(match status.pec {
        PecState::Off => b'/',
        PecState::Learning => b'^',
        PecState::Playing => b'~',
    });
}
