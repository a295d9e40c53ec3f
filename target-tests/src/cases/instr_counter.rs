//! The SysTick instruction counter (`crate::instr`) measures loops of known
//! length. `cortex_m::asm::delay(n)` runs `n + 1` iterations of a two
//! instruction loop (`subs`, `bne`), i.e. `2n + 2` instructions.

use crate::harness::{check, TestResult};
use crate::instr;
use cortex_m_semihosting::hprintln;

fn measure_delay(n: u32) -> u64 {
    instr::start();
    cortex_m::asm::delay(core::hint::black_box(n));
    instr::elapsed_instructions()
}

/// Within 1% + 4 ticks of the expected count (exact under -icount).
pub fn measures_delay_loop() -> TestResult {
    for n in [10_000u32, 500_000] {
        let got = measure_delay(n);
        let want = 2 * n as u64 + 2;
        let slack = want / 100 + 4 * instr::INSTRUCTIONS_PER_TICK;
        if got + slack < want || got > want + slack {
            hprintln!(
                "    delay({}): measured {} instructions, expected {}",
                n,
                got,
                want
            );
            return Err("delay loop count off");
        }
    }
    Ok(())
}

/// Ten times the loop measures about ten times more, also across a SysTick
/// wrap: 2^24 ticks = 671,088,640 instructions, the long loop runs 1e9.
pub fn longer_loop_measures_more() -> TestResult {
    let short = measure_delay(50_000_000);
    let long = measure_delay(500_000_000);
    hprintln!(
        "    1e8-instruction loop: {}, 1e9-instruction loop: {}",
        short,
        long
    );
    check(
        short > 0 && long > short,
        "longer loop did not measure more",
    )?;
    check(long > 9 * short && long < 11 * short, "ratio not about 10")?;
    check(
        long > 990_000_000 && long < 1_010_000_000,
        "1e9 loop off by more than 1% (SysTick wrap lost?)",
    )
}
