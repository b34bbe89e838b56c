#!/usr/bin/env bash
# Fetches Intel Open Image Denoise 2.5.1's shared libraries for `cargo build --features denoise`
# on a machine without a system package, from the PyPI wheel pyoidn 2.5.1.0 (through pip), and
# unpacks them into .oidn/lib of the repository (git ignores .oidn). The build (build.rs) finds
# them there and records their folder as the binary's rpath, so the binary runs without
# LD_LIBRARY_PATH. Run it once from anywhere:
#
#     tools/setup_oidn.sh
#
# A system OIDN (2.x, with pkg-config) needs no setup: build with the feature and nothing else.
# OIDN_DIR=/some/oidn (holding lib/libOpenImageDenoise.so) picks another copy.
set -euo pipefail
repo="$(cd "$(dirname "$0")/.." && pwd)"
dest="$repo/.oidn"
version="2.5.1.0"
libs=(libOpenImageDenoise.so.2 libOpenImageDenoise_core.so libOpenImageDenoise_device_cpu.so libtbb.so.12)

if [ -e "$dest/lib/libOpenImageDenoise.so" ] && compgen -G "$dest/lib/libOpenImageDenoise_device_cpu.so*" >/dev/null; then
    echo "OIDN already set up in $dest/lib"
    exit 0
fi
if python3 -m pip --version >/dev/null 2>&1; then
    pip=(python3 -m pip)
elif command -v pip3 >/dev/null 2>&1; then
    pip=(pip3)
else
    echo "setup_oidn: pip is missing; installing python3-pip with apt-get" >&2
    apt-get update -qq && apt-get install -y -qq python3-pip >/dev/null
    pip=(python3 -m pip)
fi

download="$(mktemp -d)"
trap 'rm -rf "$download"' EXIT
"${pip[@]}" download --quiet --no-deps --only-binary=:all: "pyoidn==$version" -d "$download"
wheel="$(ls "$download"/pyoidn-*.whl)"
python3 - "$wheel" "$dest/lib" "${libs[@]}" <<'PY'
import os, sys, zipfile
wheel, dest, *wanted = sys.argv[1:]
os.makedirs(dest, exist_ok=True)
with zipfile.ZipFile(wheel) as z:
    names = z.namelist()
    for prefix in wanted:
        # The wheel may hold the library under its full version (libOpenImageDenoise.so.2.5.1).
        found = [n for n in names if "/oidn/lib/" in n and os.path.basename(n).startswith(prefix)]
        if not found:
            sys.exit(f"setup_oidn: {prefix} is not in {os.path.basename(wheel)}")
        for name in found:
            with z.open(name) as src, open(os.path.join(dest, os.path.basename(name)), "wb") as out:
                out.write(src.read())
PY
cd "$dest/lib"
# The linker looks for libOpenImageDenoise.so; the binary records libOpenImageDenoise.so.2.
[ -e libOpenImageDenoise.so.2 ] || ln -sf "$(ls libOpenImageDenoise.so.2.* | head -n1)" libOpenImageDenoise.so.2
ln -sf libOpenImageDenoise.so.2 libOpenImageDenoise.so
echo "OIDN $version unpacked in $dest/lib; now: cargo build --release --features denoise"
