#!/usr/bin/env bash
# The project's single test command, for newcomers and CI:   ./test.sh
#
#   0. toolchain: rustup target thumbv7em-none-eabihf, llvm-tools, rustfmt,
#      clippy; flip-link (cargo install); qemu-system-arm (10 or later for
#      step 6: .ci/run installs it from Debian's backports), indi-bin and
#      chromium (installed with apt-get when run as root).
#   1. lint:         cargo fmt --check, cargo clippy -D warnings and cargo doc
#                    (rustdoc warnings are errors) in every crate.
#   2. unit tests:   the library's own tests, on the host
#                    (cargo test --release --lib --no-default-features
#                    --target <host>)
#      host tests:   cd host-tests && cargo test --release
#   3. target tests: cd target-tests && cargo run --release   (QEMU, Cortex-M4F),
#                    --bin no_panic (links only if the model's, the loop's
#                    and the command port's entry points hold no panic
#                    path), and the fault path
#                    (--bin safe_state): a panic, a
#                    HardFault and a stack overflow in the model's task end
#                    in the safe state.
#   4. firmware:     cargo build --release for each chip (the three F4
#                    boards and the B-L475E-IOT01A), with flash/RAM use;
#                    fails if the STM32F411CE build exceeds 200 KiB of flash
#                    (inside its 256 KiB code region in memory.x, sectors
#                    0-5) or 96 KiB
#                    of static RAM (the rest of its 128 KiB is left
#                    for the stack), or if its panic call sites (counted in
#                    the disassembly) exceed PANIC_SITES_MAX, or if the
#                    L475's static RAM leaves less than 16 KiB of its
#                    96 KiB for the stack, or if any function's stack
#                    frame exceeds STACK_FRAME_MAX.
#   5. bench:        cd host-tests && cargo run --release --bin guide-sim --
#                    bench --csv   (prints the figures; fails if N = 2 or 3 exceeds
#                    1,000,000 instructions per frame (median) or 64 KiB of
#                    state; about a minute, mostly QEMU)
#   6. board:        the whole binary booted in QEMU's b-l475e-iot01a:
#                    target-tests/board/build.sh (and again with each
#                    test-only feature: inject-model-fault, emulator-tick),
#                    then MKGP_BOARD_ELF=<its ELF>
#                    MKGP_BOARD_FAULT_ELF=<inject-model-fault's>
#                    MKGP_BOARD_LONG_ELF=<emulator-tick's>
#                    cargo test --release --test board in host-tests
#                    (start-up, tracking, ST4, guiding that the model learns
#                    from, the stack, INDI's indi_lx200generic on the
#                    emulated USART, the fault path as wired, 31 emulated
#                    minutes with the store's restores and saves; about 12
#                    minutes)
#
# Exits non-zero on the first failure.
set -euo pipefail
cd "$(dirname "$0")"

TARGET=thumbv7em-none-eabihf
CHIPS=(stm32f411ce stm32f446re stm32f407vg stm32l475vg)
# Issue 29's goal, inside the code region of memory.x (256 KiB, sectors
# 0-5; sectors 6-7 are storage), reached by the code generation of
# .cargo/config.toml (docs/decisions.md, "Flash: what costs the most").
F411_FLASH_MAX=$((200 * 1024))
F411_RAM_MAX=$((96 * 1024))
# The L475's RAM is 96 KiB (SRAM1; memory.x): at least 16 KiB of it stays
# for the stack, whose high-water mark host-tests/tests/board.rs measures.
L475_RAM_MAX=$((80 * 1024))
# Panic call sites in the F411 release ELF: a ratchet, lowered as they go.
# None are the model's, the loop's or the port's: no_panic proves those
# paths free of them. 27 are embassy's executor, drivers and defmt; 152
# came with embassy-usb's stack (docs/decisions.md, "USB serial"); 139 with
# the store and the worm-index input (sequential-storage's map, our async
# store code around it and embassy's EXTI future; docs/decisions.md,
# "Persistence"). Issue 29's smaller inlining and dependencies at "z" left
# 12 fewer (sites merged, not removed): 306; the learning policy's move
# into the library (issue 28) one fewer: 305; no runtime unrolling (issue
# 29) two copies more of embassy-sync's pipe borrow inlined into a task: 307;
# the worm index's own interrupt handler instead of embassy's EXTI future: 303.
PANIC_SITES_MAX=303
# The largest stack frame of any one function (the model's frame is the
# largest; docs/results.md has its size). A large value built in a stack
# temporary (the grid's 16 KiB, once) overflows the L475's 20 KiB stack at
# boot, which only the board step would otherwise show.
STACK_FRAME_MAX=8192

kib() { printf '%d.%d KiB' $(($1 / 1024)) $((($1 % 1024) * 10 / 1024)); }
step() { printf '\n==> %s\n' "$*"; }
die() { printf 'test.sh: error: %s\n' "$*" >&2; exit 1; }

# --- 0. toolchain -----------------------------------------------------------
step "toolchain"
command -v cargo >/dev/null || die "cargo not found: install Rust with rustup (https://rustup.rs)"
command -v rustup >/dev/null || die "rustup not found: the embedded target is installed with rustup"
if ! rustup target list --installed | grep -qx "$TARGET"; then
    rustup target add "$TARGET"
fi
installed_components=$(rustup component list --installed)
for c in llvm-tools rustfmt clippy; do
    if ! grep -q "^$c" <<<"$installed_components"; then
        rustup component add "$c"
    fi
done
# flip-link: the firmware's (and target-tests') linker, stack below statics.
if ! command -v flip-link >/dev/null; then
    cargo install flip-link --locked
fi
if ! command -v qemu-system-arm >/dev/null; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        export DEBIAN_FRONTEND=noninteractive
        apt-get update
        apt-get install -y --no-install-recommends qemu-system-arm
    else
        die "qemu-system-arm not found: install it (Debian/Ubuntu: sudo apt-get install qemu-system-arm)"
    fi
fi
# Installs Debian package $2 (for command $1) with apt-get when run as root;
# otherwise says that the test it is for ($3) will be skipped (under
# CI=true that test fails instead).
optional_package() {
    command -v "$1" >/dev/null && return
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        export DEBIAN_FRONTEND=noninteractive
        apt-get update
        apt-get install -y --no-install-recommends "$2"
    else
        echo "$1 not found: $3 will be skipped (Debian/Ubuntu: sudo apt-get install $2)"
    fi
}
# INDI's indi_lx200generic against guide-sim mount (host-tests/tests/indi.rs).
optional_package indiserver indi-bin "the INDI test"
# guide-sim view's page in a real browser (host-tests/tests/view.rs).
optional_package chromium chromium "the view's browser test"
HOST=$(rustc -vV | sed -n 's/^host: //p')
LLVM_BIN="$(rustc --print sysroot)/lib/rustlib/$HOST/bin"
LLVM_SIZE="$LLVM_BIN/llvm-size"
LLVM_OBJDUMP="$LLVM_BIN/llvm-objdump"
[ -x "$LLVM_SIZE" ] && [ -x "$LLVM_OBJDUMP" ] ||
    die "llvm-size or llvm-objdump not found in $LLVM_BIN (rustup component add llvm-tools)"
echo "rustc: $(rustc --version)"
echo "flip-link: $(command -v flip-link)"
echo "qemu:  $(qemu-system-arm --version | head -n1)"

HAVE_HOST_TESTS=0
[ -f host-tests/Cargo.toml ] && HAVE_HOST_TESTS=1

# --- 1. lint -------------------------------------------------------------------
step "cargo fmt --check"
cargo fmt --all --check # firmware package and hal/
(cd target-tests && cargo fmt --check)
if [ "$HAVE_HOST_TESTS" = 1 ]; then
    (cd host-tests && cargo fmt --check)
fi

step "cargo clippy -D warnings"
cargo clippy --release -- -D warnings # firmware, library and hal/ for the target
cargo clippy --release --lib --tests --no-default-features --target "$HOST" -- -D warnings
(cd target-tests && cargo clippy --release --bins -- -D warnings)
if [ "$HAVE_HOST_TESTS" = 1 ]; then
    (cd host-tests && cargo clippy --release --all-targets -- -D warnings)
fi

step "cargo doc (warnings are errors)"
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --workspace
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --lib --no-default-features --target "$HOST"
(cd target-tests && RUSTDOCFLAGS="-D warnings" cargo doc --no-deps)
if [ "$HAVE_HOST_TESTS" = 1 ]; then
    (cd host-tests && RUSTDOCFLAGS="-D warnings" cargo doc --no-deps)
fi

# --- 2. the library's unit tests and the host tests ---------------------------
step "library unit tests (cargo test --release --lib on $HOST)"
cargo test --release --lib --no-default-features --target "$HOST"

if [ "$HAVE_HOST_TESTS" = 1 ]; then
    step "host tests (host-tests: cargo test --release)"
    (cd host-tests && cargo test --release)
else
    step "host tests: host-tests/Cargo.toml not found, skipped"
fi

# --- 3. target tests in QEMU --------------------------------------------------
step "target-tests harness self-check (failures must be reported)"
selfcheck() {
    local feature=$1 want=$2 log rc
    log=$(mktemp)
    rc=0
    (cd target-tests && cargo run --release --features "$feature") >"$log" 2>&1 </dev/null || rc=$?
    if [ "$rc" = 0 ] || ! grep -qx "$want" "$log"; then
        cat "$log" >&2
        rm -f "$log"
        die "target-tests self-check $feature: expected a non-zero exit and '$want' (exit was $rc)"
    fi
    rm -f "$log"
    echo "$feature: exit $rc, reported '$want' as expected"
}
selfcheck selfcheck-fail "1 passed, 2 failed"
selfcheck selfcheck-hardfault "1 passed, 1 failed"

step "target tests (target-tests: cargo run --release in qemu-system-arm mps2-an386)"
(cd target-tests && cargo run --release </dev/null)

# The panic handler of --bin no_panic calls an undefined function: it links
# (and then runs) only if no panic path is left in the guider's entry points.
step "no panic in the model (target-tests: --bin no_panic links only without a panic path)"
(cd target-tests && cargo run --release --bin no_panic </dev/null)

step "fault path (target-tests: --bin safe_state, a panic, a HardFault and a stack overflow in the model's task)"
for fault in "" safe-state-hardfault safe-state-stack-overflow; do
    (cd target-tests && cargo run --release --bin safe_state ${fault:+--features "$fault"} </dev/null)
done

# --- 4. firmware builds, sizes and panic sites ----------------------------------

# Call sites of panic entry points in an ELF: branches (bl, b.w, b) to the
# start of a core panic function, from code outside the panic machinery.
# With BY_FUNCTION=1 also lists the calling functions.
panic_sites() {
    "$LLVM_OBJDUMP" -d --demangle --no-show-raw-insn "$1" | awk '
        function is_panic(sym) {
            return sym ~ /^(core::panicking::|core::slice::index::slice_[a-z_]*fail|core::option::(unwrap|expect)_failed|core::result::unwrap_failed|core::cell::panic_already|_defmt_panic|__defmt_default_panic|rust_begin_unwind)/
        }
        /^[0-9a-f]+ <.*>:$/ {
            fn = $0; sub(/^[0-9a-f]+ </, "", fn); sub(/>:$/, "", fn)
            inside = is_panic(fn)
            next
        }
        /\t(bl|b\.w|b)\t/ && !inside && match($0, /<[^>]*>/) {
            target = substr($0, RSTART + 1, RLENGTH - 2)
            if (target !~ /\+0x/ && is_panic(target)) { n++; by[target]++; from[fn]++ }
        }
        END {
            for (t in by) printf "%6d  %s\n", by[t], t | "sort -rn"
            close("sort -rn")
            if (ENVIRON["BY_FUNCTION"] != "") {
                for (f in from) printf "%6d  in %s\n", from[f], f | "sort -rn"
                close("sort -rn")
            }
            printf "total %d\n", n
        }'
}

# The largest stack frames in an ELF: the immediate of each `sub sp`
# (bytes) and its function, largest first (five of them).
stack_frames() {
    "$LLVM_OBJDUMP" -d --demangle --no-show-raw-insn "$1" | awk '
        function value(s,    i, c, v) {
            if (s !~ /^0x/) return s + 0
            v = 0
            for (i = 3; i <= length(s); i++) {
                c = index("0123456789abcdef", substr(s, i, 1)) - 1
                v = v * 16 + c
            }
            return v
        }
        /^[0-9a-f]+ <.*>:$/ { fn = $0; sub(/^[0-9a-f]+ </, "", fn); sub(/>:$/, "", fn); next }
        /\tsub(\.w|w)?\t+sp, (sp, )?#/ {
            imm = $0; sub(/.*#/, "", imm); sub(/[^0-9a-fx].*/, "", imm)
            printf "%d %s\n", value(imm), fn
        }' | sort -rn | awk 'NR <= 5'
}

step "firmware builds"
OUT="target/$TARGET/release"
sizes=()
for chip in "${CHIPS[@]}"; do
    echo "--- $chip"
    cargo build --release --no-default-features --features "$chip"
    cp "$OUT/mkgp-mount" "$OUT/mkgp-mount-$chip"
    read -r text data bss _ < <("$LLVM_SIZE" -B "$OUT/mkgp-mount-$chip" | tail -n1)
    flash=$((text + data))
    # The L475's .sram2 (its 32 KiB SRAM2: the snapshot buffer) is not the
    # RAM the stack shares.
    sram2=$("$LLVM_SIZE" -A "$OUT/mkgp-mount-$chip" | awk '$1 == ".sram2" { print $2 }')
    ram=$((data + bss - ${sram2:-0}))
    sizes+=("$(printf '%-12s %9d B %12s %9d B %12s' "$chip" "$flash" "($(kib "$flash"))" \
        "$ram" "($(kib "$ram"))")")
    if [ "$chip" = stm32f411ce ]; then
        f411_flash=$flash
        f411_ram=$ram
    fi
    if [ "$chip" = stm32l475vg ]; then
        l475_ram=$ram
    fi
done

step "firmware size (flash = text + data, static RAM = data + bss but the L475's SRAM2; stack not included)"
printf '%-12s %24s %24s\n' chip flash "static RAM"
printf '%s\n' "${sizes[@]}"
echo "ELF per chip: $OUT/mkgp-mount-<chip>"
[ "$f411_flash" -le "$F411_FLASH_MAX" ] ||
    die "stm32f411ce flash $f411_flash B exceeds the budget of $F411_FLASH_MAX B"
[ "$f411_ram" -le "$F411_RAM_MAX" ] ||
    die "stm32f411ce static RAM $f411_ram B exceeds the budget of $F411_RAM_MAX B"
echo "stm32f411ce within budget (flash <= $((F411_FLASH_MAX / 1024)) KiB, static RAM <= 96 KiB)"
[ "$l475_ram" -le "$L475_RAM_MAX" ] ||
    die "stm32l475vg static RAM $l475_ram B exceeds $L475_RAM_MAX B (less than 16 KiB of stack)"
echo "stm32l475vg within budget (static RAM <= $((L475_RAM_MAX / 1024)) KiB)"

step "panic call sites in the stm32f411ce release ELF (at most $PANIC_SITES_MAX)"
sites=$(panic_sites "$OUT/mkgp-mount-stm32f411ce")
echo "$sites"
total=$(tail -n1 <<<"$sites" | awk '{print $2}')
[ "$total" -le "$PANIC_SITES_MAX" ] ||
    die "$total panic call sites, more than $PANIC_SITES_MAX (BY_FUNCTION=1 lists where)"

step "largest stack frames in the release ELFs (at most $STACK_FRAME_MAX B each)"
for chip in "${CHIPS[@]}"; do
    frames=$(stack_frames "$OUT/mkgp-mount-$chip")
    largest=$(head -n1 <<<"$frames")
    echo "$chip: $largest"
    [ "${largest%% *}" -le "$STACK_FRAME_MAX" ] ||
        die "$chip: a stack frame of more than $STACK_FRAME_MAX B:"$'\n'"$frames"
done

# --- 5. bench -----------------------------------------------------------------
# The figures, and the Cortex-M4 goals asserted by the bench binary: host
# time per frame (f64/f32, 1, 2 and 3 stages, printed only) and, from
# target-tests' bench binary in QEMU, instructions per frame of the f32
# guider on the Cortex-M4 and the bytes of model state.
if [ "$HAVE_HOST_TESTS" = 1 ]; then
    step "bench (host-tests: cargo run --release --bin guide-sim -- bench --csv)"
    (cd host-tests && cargo run --release --bin guide-sim -- bench --csv </dev/null)
fi

# --- 6. the whole binary in QEMU ------------------------------------------------
if [ "$HAVE_HOST_TESTS" = 1 ]; then
    if qemu-system-arm -M help | grep -q '^b-l475e-iot01a'; then
        step "board (the stm32l475vg binary booted in QEMU's b-l475e-iot01a)"
        fault_elf=$(target-tests/board/build.sh inject-model-fault)
        long_elf=$(target-tests/board/build.sh emulator-tick)
        board_elf=$(target-tests/board/build.sh)
        (cd host-tests && MKGP_BOARD_ELF="$board_elf" MKGP_BOARD_FAULT_ELF="$fault_elf" \
            MKGP_BOARD_LONG_ELF="$long_elf" \
            cargo test --release --test board -- --nocapture </dev/null)
    elif [ "${CI:-}" = true ]; then
        die "QEMU has no b-l475e-iot01a machine (QEMU 10 or later; .ci/run installs it from backports)"
    else
        step "board: QEMU has no b-l475e-iot01a machine (QEMU 10 or later), skipped"
    fi
fi

step "all checks passed"
