#!/usr/bin/env bash
# Builds the firmware for the B-L475E-IOT01A (feature stm32l475vg) as QEMU
# 10's b-l475e-iot01a machine can run it, and prints the ELF's path.
#
# The firmware's sources are built as they are, against a copy of
# embassy-stm32 with embassy-stm32.patch applied (the places where QEMU's
# model of the chip differs from the silicon; the patch says which). All of
# it happens under target/board-qemu/: a copy of the workspace whose
# .cargo/config.toml adds the [patch], so that the repository's own
# Cargo.lock and builds are not touched.
#
#   target-tests/board/build.sh          # prints target/board-qemu/mkgp-mount
#   target-tests/board/build.sh FEATURE  # with a test-only feature of the
#                                        # firmware too (inject-model-fault):
#                                        # target/board-qemu/mkgp-mount-FEATURE
set -euo pipefail
features=stm32l475vg${1:+,$1}
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
out="$root/target/board-qemu"

die() { printf 'board/build.sh: error: %s\n' "$*" >&2; exit 1; }
command -v patch >/dev/null || die "patch not found (apt-get install patch)"

# The embassy-stm32 the lock file names, as cargo unpacked it.
cd "$root"
cargo fetch --target thumbv7em-none-eabihf >&2
manifest=$(cargo metadata --format-version 1 --filter-platform thumbv7em-none-eabihf |
    python3 -c 'import json, sys
for p in json.load(sys.stdin)["packages"]:
    if p["name"] == "embassy-stm32" and p["source"]:
        print(p["manifest_path"]); break')
[ -n "$manifest" ] || die "embassy-stm32 not found in cargo metadata"

rm -rf "$out/embassy-stm32" "$out/ws"
mkdir -p "$out/ws"
cp -r "$(dirname "$manifest")" "$out/embassy-stm32"
patch --quiet -d "$out/embassy-stm32" -p1 <"$here/embassy-stm32.patch" ||
    die "embassy-stm32.patch does not apply to $(dirname "$manifest")"

cp -r Cargo.toml Cargo.lock build.rs memory.x src hal .cargo "$out/ws/"
cat >>"$out/ws/.cargo/config.toml" <<TOML

[patch.crates-io]
embassy-stm32 = { path = "$out/embassy-stm32" }
TOML
(cd "$out/ws" && CARGO_TARGET_DIR="$out/target" cargo build --release \
    --no-default-features --features "$features" >&2)
# Each build's ELF kept apart: the next build overwrites cargo's.
elf="$out/mkgp-mount${1:+-$1}"
cp "$out/target/thumbv7em-none-eabihf/release/mkgp-mount" "$elf"
echo "$elf"
