#!/usr/bin/env bash
# Builds the firmware for the B-L475E-IOT01A (feature stm32l475vg) as QEMU
# 10's b-l475e-iot01a machine can run it, and prints the ELF's path.
#
# The firmware's sources are built as they are, against copies of
# embassy-stm32 and embassy-executor with this folder's patches applied
# (the places where QEMU's model of the chip differs from the silicon; each
# patch says which). All of it happens under target/board-qemu/: a copy of
# the workspace whose .cargo/config.toml adds the [patch], so that the
# repository's own Cargo.lock and builds are not touched.
#
#   target-tests/board/build.sh          # prints target/board-qemu/mkgp-mount
#   target-tests/board/build.sh FEATURE  # with a test-only feature of the
#                                        # firmware too (inject-model-fault,
#                                        # emulator-tick):
#                                        # target/board-qemu/mkgp-mount-FEATURE
set -euo pipefail
features=stm32l475vg${1:+,$1}
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
out="$root/target/board-qemu"

die() { printf 'board/build.sh: error: %s\n' "$*" >&2; exit 1; }
command -v patch >/dev/null || die "patch not found (apt-get install patch)"

# Each crate with a patch here (<crate>.patch): the version the lock file
# names, as cargo unpacked it, copied and patched, and named in the
# workspace copy's [patch].
cd "$root"
cargo fetch --target thumbv7em-none-eabihf >&2
metadata=$(cargo metadata --format-version 1 --filter-platform thumbv7em-none-eabihf)
rm -rf "$out/ws" "$out/patched"
mkdir -p "$out/ws" "$out/patched"
cp -r Cargo.toml Cargo.lock build.rs memory.x src hal .cargo "$out/ws/"
printf '\n[patch.crates-io]\n' >>"$out/ws/.cargo/config.toml"
for patch in "$here"/*.patch; do
    crate=$(basename "$patch" .patch)
    manifest=$(printf '%s' "$metadata" | python3 -c 'import json, sys
for p in json.load(sys.stdin)["packages"]:
    if p["name"] == sys.argv[1] and p["source"]:
        print(p["manifest_path"]); break' "$crate")
    [ -n "$manifest" ] || die "$crate not found in cargo metadata"
    cp -r "$(dirname "$manifest")" "$out/patched/$crate"
    patch --quiet -d "$out/patched/$crate" -p1 <"$patch" ||
        die "$crate.patch does not apply to $(dirname "$manifest")"
    printf '%s = { path = "%s" }\n' "$crate" "$out/patched/$crate" >>"$out/ws/.cargo/config.toml"
done
(cd "$out/ws" && CARGO_TARGET_DIR="$out/target" cargo build --release \
    --no-default-features --features "$features" >&2)
# Each build's ELF kept apart: the next build overwrites cargo's.
elf="$out/mkgp-mount${1:+-$1}"
cp "$out/target/thumbv7em-none-eabihf/release/mkgp-mount" "$elf"
echo "$elf"
