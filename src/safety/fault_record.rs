//! What a fault leaves for the next boot: the kind of fault and where it
//! happened, as words in RAM that the reset does not clear.
//!
//! Such RAM holds garbage after a power-on, so a record carries a magic word
//! and a checksum and decodes only when both match: random RAM passes with a
//! probability of about 2^-64. The boot reads the record once and clears it,
//! so a record seen at boot belongs to the reset just before.

/// Bytes of the source file name a panic record keeps: the end of the path,
/// which names the module.
pub const FILE_BYTES: usize = 48;
/// Words of an encoded record (72 bytes of RAM).
pub const RECORD_WORDS: usize = HEADER_WORDS + FILE_BYTES / 4 + 1;

const HEADER_WORDS: usize = 5;
/// "MKGF": marks a record written by this firmware's fault path.
const MAGIC: u32 = 0x4D4B_4746;

/// The part of the firmware that stopped making progress.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    /// The step-tick interrupt: the motors no longer follow the rates.
    StepTick,
    /// The learner (the model, in thread mode): frames wait unlearned.
    Learner,
}

impl Part {
    pub fn name(self) -> &'static str {
        match self {
            Part::StepTick => "step tick",
            Part::Learner => "learner",
        }
    }
}

/// What went wrong.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    /// A panic at `line` of [`FaultRecord::file`].
    Panic { line: u32 },
    /// A HardFault with the faulting instruction at `pc` and the return
    /// address `lr` from the exception frame.
    HardFault { pc: u32, lr: u32 },
    /// The liveness check found `Part` stalled.
    Stalled(Part),
    /// A HardFault whose exception frame could not be stacked: the stack
    /// ran out (its guard below it faulted).
    StackOverflow,
}

impl Fault {
    fn code(self) -> (u32, u32, u32) {
        match self {
            Fault::Panic { line } => (1, line, 0),
            Fault::HardFault { pc, lr } => (2, pc, lr),
            Fault::Stalled(Part::StepTick) => (3, 0, 0),
            Fault::Stalled(Part::Learner) => (4, 0, 0),
            Fault::StackOverflow => (5, 0, 0),
        }
    }

    fn from_code(kind: u32, a: u32, b: u32) -> Option<Self> {
        Some(match kind {
            1 => Fault::Panic { line: a },
            2 => Fault::HardFault { pc: a, lr: b },
            3 => Fault::Stalled(Part::StepTick),
            4 => Fault::Stalled(Part::Learner),
            5 => Fault::StackOverflow,
            _ => return None,
        })
    }
}

/// One fault, as kept across the reset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FaultRecord {
    fault: Fault,
    file: [u8; FILE_BYTES],
    file_len: u8,
}

impl FaultRecord {
    /// A panic at `file:line`. A longer path keeps its last
    /// [`FILE_BYTES`] bytes, cut at a character boundary.
    pub fn panic(file: &str, line: u32) -> Self {
        let bytes = file.as_bytes();
        let mut start = bytes.len().saturating_sub(FILE_BYTES);
        while !file.is_char_boundary(start) {
            start += 1;
        }
        let tail = bytes.get(start..).unwrap_or_default();
        let mut record = Self::without_file(Fault::Panic { line });
        for (dst, src) in record.file.iter_mut().zip(tail) {
            *dst = *src;
        }
        record.file_len = tail.len().min(FILE_BYTES) as u8;
        record
    }

    /// The panic of a panic handler: its location only (formatting the
    /// message would pull core's formatting machinery into the binary).
    pub fn from_panic(info: &core::panic::PanicInfo) -> Self {
        info.location()
            .map_or_else(|| Self::panic("", 0), |l| Self::panic(l.file(), l.line()))
    }

    pub fn hard_fault(pc: u32, lr: u32) -> Self {
        Self::without_file(Fault::HardFault { pc, lr })
    }

    pub fn stalled(part: Part) -> Self {
        Self::without_file(Fault::Stalled(part))
    }

    pub fn stack_overflow() -> Self {
        Self::without_file(Fault::StackOverflow)
    }

    fn without_file(fault: Fault) -> Self {
        FaultRecord {
            fault,
            file: [0; FILE_BYTES],
            file_len: 0,
        }
    }

    pub fn fault(&self) -> Fault {
        self.fault
    }

    /// The source file of a panic (the end of its path); empty otherwise.
    pub fn file(&self) -> &str {
        let bytes = self
            .file
            .get(..usize::from(self.file_len))
            .unwrap_or_default();
        core::str::from_utf8(bytes).unwrap_or("?")
    }

    pub fn encode(&self) -> [u32; RECORD_WORDS] {
        let mut words = [0u32; RECORD_WORDS];
        let (kind, a, b) = self.fault.code();
        words[0] = MAGIC;
        words[1] = kind;
        words[2] = a;
        words[3] = b;
        words[4] = u32::from(self.file_len);
        for (word, chunk) in words[HEADER_WORDS..]
            .iter_mut()
            .zip(self.file.chunks_exact(4))
        {
            *word = u32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
        }
        words[RECORD_WORDS - 1] = checksum(&words[..RECORD_WORDS - 1]);
        words
    }

    /// The record in `words`, or `None` for anything this firmware's fault
    /// path did not write whole (power-on garbage, a cleared record).
    pub fn decode(words: &[u32; RECORD_WORDS]) -> Option<Self> {
        let (body, sum) = words.split_at(RECORD_WORDS - 1);
        if words[0] != MAGIC || sum != [checksum(body)] {
            return None;
        }
        let fault = Fault::from_code(words[1], words[2], words[3])?;
        let file_len = u8::try_from(words[4])
            .ok()
            .filter(|&n| usize::from(n) <= FILE_BYTES)?;
        let mut file = [0u8; FILE_BYTES];
        for (chunk, word) in file.chunks_exact_mut(4).zip(&words[HEADER_WORDS..]) {
            chunk.copy_from_slice(&word.to_le_bytes());
        }
        Some(FaultRecord {
            fault,
            file,
            file_len,
        })
    }
}

/// FNV-1a over the words.
fn checksum(words: &[u32]) -> u32 {
    words
        .iter()
        .fold(0x811C_9DC5, |h, &w| (h ^ w).wrapping_mul(0x0100_0193))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_fault_survives_the_round_trip() {
        let records = [
            FaultRecord::panic("src/model/gp/infer.rs", 212),
            FaultRecord::hard_fault(0x0800_1234, 0x0800_5679),
            FaultRecord::stalled(Part::StepTick),
            FaultRecord::stalled(Part::Learner),
            FaultRecord::stack_overflow(),
        ];
        for r in records {
            assert_eq!(FaultRecord::decode(&r.encode()), Some(r));
        }
        assert_eq!(records[0].file(), "src/model/gp/infer.rs");
        assert_eq!(records[0].fault(), Fault::Panic { line: 212 });
        assert_eq!(records[1].file(), "");
    }

    #[test]
    fn a_long_path_keeps_its_end_at_a_character_boundary() {
        let long = "/home/someone/ünïcödé/projects/mkgp-mount/src/model/gp/infer.rs";
        let r = FaultRecord::panic(long, 7);
        assert!(long.ends_with(r.file()));
        assert!(r.file().len() <= FILE_BYTES && r.file().len() >= FILE_BYTES - 3);
        assert_eq!(
            FaultRecord::decode(&r.encode()).map(|d| d.file().len()),
            Some(r.file().len())
        );
    }

    #[test]
    fn cleared_or_damaged_words_are_no_record() {
        assert_eq!(FaultRecord::decode(&[0; RECORD_WORDS]), None);
        let good = FaultRecord::panic("a.rs", 1).encode();
        for i in 0..RECORD_WORDS {
            for bit in [0, 7, 31] {
                let mut bad = good;
                bad[i] ^= 1 << bit;
                assert_eq!(FaultRecord::decode(&bad), None, "word {i} bit {bit}");
            }
        }
    }

    #[test]
    fn random_words_never_decode_and_never_panic() {
        let mut rng = crate::testing::SplitMix64::new(7);
        for _ in 0..200_000 {
            let mut words = [0u32; RECORD_WORDS];
            for w in &mut words {
                *w = rng.next_u64() as u32;
            }
            // Half the draws carry the magic, so the checksum is what refuses them.
            if rng.below(2) == 0 {
                words[0] = MAGIC;
            }
            assert_eq!(FaultRecord::decode(&words), None);
        }
    }
}
