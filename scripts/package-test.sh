#!/usr/bin/env bash
# make test-package (called by make test, after make test-aarch64): the Debian packages and the
# installed library, end to end, for amd64 and arm64 (docs/api.md "Debian packages").
#
#   1. amd64: Release build of the library and programs only (preset `package`), cpack -> debs;
#      arm64: cpack over the aarch64-release build make test-aarch64 already built.
#   2. Both: dpkg-deb contents and control fields, the systemd drop-ins' limits.
#   3. Depends: amd64's come from dpkg-shlibdeps and must be installable on this Debian
#      (apt-get --simulate); arm64's stated list must equal them, and the arm64 binaries must
#      need no shared library the amd64 ones do not, each present in the arm64 sysroot.
#   4. Install each architecture's debs into a scratch root with dpkg --root (a real dpkg
#      install: file database, no maintainer scripts to run; dependencies are forced because the
#      scratch root is empty - step 3 checks them - and the programs then run against this host's
#      libraries, or the sysroot's under qemu: the same Debian 12 packages the Depends name).
#   5. From the installed files: zonemap --help, a small simulated scenario (amd64 zonemap sim),
#      a short zonemapd replay with the installed profile; arm64 under qemu-aarch64.
#   6. A separate consumer project (examples/embed) built against the installed CMake package
#      (amd64; arm64 cross-configured with the project's toolchain file and sysroot, run under
#      qemu), and the same program built with pkg-config alone.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$PWD
sysroot=${ZM_ARM64_SYSROOT:-/opt/zonemap/sysroot-arm64}
jobs=${JOBS:-$(nproc)}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
t0=$(date +%s)
step() { echo "package-test: [$(( $(date +%s) - t0 )) s] $*"; }
fail() { echo "package-test: FAILED: $*" >&2; exit 1; }
qemu=(qemu-aarch64 -L "$sysroot")

# ---- 1. Build and package -------------------------------------------------------------------
step "amd64: configure and build (Release, library and programs only)"
cmake --preset package >/dev/null
cmake --build --preset package -j "$jobs"
rm -rf build/package/packages
(cd build/package && cpack -G DEB >/dev/null)
step "arm64: package the aarch64-release build"
cmake --preset aarch64-release >/dev/null
cmake --build --preset aarch64-release -j "$jobs" >/dev/null
rm -rf build/aarch64-release/packages
(cd build/aarch64-release && cpack -G DEB >/dev/null)

version=$(sed -n 's/^project(zonemap VERSION \([0-9.]*\).*/\1/p' CMakeLists.txt)
deb() { echo "build/$1/packages/$2_${version}-1_$3.deb"; }
rt64=$(deb package zonemap amd64); dev64=$(deb package libzonemap-dev amd64)
rtarm=$(deb aarch64-release zonemap arm64); devarm=$(deb aarch64-release libzonemap-dev arm64)
for f in "$rt64" "$dev64" "$rtarm" "$devarm"; do
  [ -f "$f" ] || fail "missing package $f"
  echo "  $f: $(du -h "$f" | cut -f1)"
done

# ---- 2. Contents and control fields ---------------------------------------------------------
step "contents and control fields"
check_deb() {  # deb package arch triplet
  local f=$1 pkg=$2 arch=$3 triplet=$4
  [ "$(dpkg-deb -f "$f" Package)" = "$pkg" ] || fail "$f: Package is not $pkg"
  [ "$(dpkg-deb -f "$f" Architecture)" = "$arch" ] || fail "$f: Architecture is not $arch"
  [ "$(dpkg-deb -f "$f" Version)" = "${version}-1" ] || fail "$f: Version is not ${version}-1"
  [ -n "$(dpkg-deb -f "$f" Depends)" ] || fail "$f: no Depends"
  [ -n "$(dpkg-deb -f "$f" Description)" ] || fail "$f: no Description"
  local contents
  contents=$(dpkg-deb -c "$f" | awk '{print $6}')
  shift 4
  for want in "$@"; do
    want=${want//@T@/$triplet}
    grep -qx "./$want" <<<"$contents" || fail "$f lacks /$want"
  done
  echo "$contents"
}
runtime_files=(usr/bin/zonemap usr/bin/zonemapd usr/bin/zonemap-cotenant
  usr/share/zonemap/profiles/orin-nano-8gb.toml usr/share/zonemap/profiles/host.toml
  usr/share/zonemap/zonemapd.env.example usr/lib/systemd/system/zonemapd@.service
  usr/lib/systemd/system/zonemapd@orin-nano-8gb.service.d/50-budget.conf)
dev_files=(usr/include/zonemap/zonemap.h usr/include/zonemap/zone_manager.h
  usr/include/zonemap/map_loop.h usr/lib/@T@/libzonemap.a
  usr/lib/@T@/cmake/zonemap/zonemapConfig.cmake usr/lib/@T@/cmake/zonemap/zonemapTargets.cmake
  usr/lib/@T@/pkgconfig/zonemap.pc)
check_deb "$rt64" zonemap amd64 x86_64-linux-gnu "${runtime_files[@]}" >/dev/null
check_deb "$rtarm" zonemap arm64 aarch64-linux-gnu "${runtime_files[@]}" >/dev/null
for pair in "$dev64:x86_64-linux-gnu" "$devarm:aarch64-linux-gnu"; do
  contents=$(check_deb "${pair%%:*}" libzonemap-dev "$(dpkg-deb -f "${pair%%:*}" Architecture)" \
    "${pair##*:}" "${dev_files[@]}")
  # Only the public headers: the core's own headers never leave the build.
  extra=$(grep '^\./usr/include/' <<<"$contents" | grep -v '^\./usr/include/$' |
          grep -v '^\./usr/include/zonemap/' || true)
  [ -z "$extra" ] || fail "${pair%%:*} installs non-public headers: $extra"
done
machine() { readelf -h "$1" | sed -n 's/^ *Machine: *//p'; }
for f in "$rt64" "$rtarm"; do
  dpkg-deb --fsys-tarfile "$f" | tar -xO ./usr/bin/zonemapd > "$work/zonemapd.bin"
  want=$( [ "$(dpkg-deb -f "$f" Architecture)" = arm64 ] && echo AArch64 || echo X86-64)
  machine "$work/zonemapd.bin" | grep -q "$want" || fail "$f: zonemapd is not built for $want"
done
echo "  zonemap Depends (amd64, dpkg-shlibdeps): $(dpkg-deb -f "$rt64" Depends)"
echo "  libzonemap-dev Depends: $(dpkg-deb -f "$dev64" Depends)"

# ---- 3. Depends -----------------------------------------------------------------------------
step "Depends: amd64 installable here, arm64 list = amd64's, arm64 NEEDED within amd64's"
sim=$(apt-get install --simulate "./$rt64" "./$dev64" 2>&1) || fail "apt-get --simulate: $sim"
grep -qE "unmet|Broken|not installable" <<<"$sim" && fail "unsatisfiable Depends: $sim"
[ "$(dpkg-deb -f "$rtarm" Depends)" = "$(dpkg-deb -f "$rt64" Depends)" ] ||
  fail "arm64 Depends (ZM_DEB_CROSS_DEPENDS, cmake/ZmPackaging.cmake) differ from amd64's computed ones:
  arm64: $(dpkg-deb -f "$rtarm" Depends)
  amd64: $(dpkg-deb -f "$rt64" Depends)"
needed() {  # deb -> sorted NEEDED sonames of its programs
  local d; d=$(mktemp -d -p "$work")
  dpkg-deb -x "$1" "$d"
  for b in "$d"/usr/bin/*; do readelf -d "$b" | sed -n 's/.*Shared library: \[\(.*\)\]/\1/p'; done | sort -u
}
# The dynamic loader's name is the architecture's own. A library the arm64 link took statically
# (the sysroot's libz.so is an absolute symlink, so CMake finds libz.a) leaves a Depends entry
# that is satisfiable and unused; a library only arm64 needs would be a missing Depends.
n64=$(needed "$rt64" | sed 's/^ld-linux-.*/ld-linux/'); narm=$(needed "$rtarm" | sed 's/^ld-linux-.*/ld-linux/')
only_arm=$(comm -13 <(echo "$n64") <(echo "$narm"))
[ -z "$only_arm" ] || fail "arm64 programs need libraries the amd64 ones (whose packages are the Depends) do not: $only_arm"
only_amd=$(comm -23 <(echo "$n64") <(echo "$narm") | tr '\n' ' ')
[ -z "$only_amd" ] || echo "  needed on amd64 only (linked statically on arm64): $only_amd"
for so in $(needed "$rtarm"); do
  [ -e "$sysroot/usr/lib/aarch64-linux-gnu/$so" ] || [ -e "$sysroot/lib/aarch64-linux-gnu/$so" ] ||
    fail "arm64 needs $so, which is not in the sysroot $sysroot"
done
for p in $(dpkg-deb -f "$rtarm" Depends | tr ',' '\n' | sed 's/(.*)//; s/ //g'); do
  [ -d "$sysroot/usr/share/doc/$p" ] || fail "arm64 Depends names $p, absent from the arm64 archive closure"
done
# The version floors (libc6 >= 2.35, libstdc++6 >= 11, ...) were computed from the amd64
# programs' symbol versions; the arm64 programs must not need newer ones.
maxver() {  # deb prefix -> the highest symbol version of that prefix its programs need
  local d; d=$(mktemp -d -p "$work")
  dpkg-deb -x "$1" "$d"
  for b in "$d"/usr/bin/*; do readelf -V "$b"; done | grep -o "Name: $2[0-9.]*" | sed "s/Name: $2//" |
    sort -V | tail -1
}
# Not GCC_: libgcc_s numbers its symbol versions per architecture (aarch64's start later, and
# main's code now reaches a GCC_4.2.0 one there), and every libgcc-s1 package (GCC 10 on) has them.
for v in GLIBC_ GLIBCXX_ CXXABI_; do
  a=$(maxver "$rt64" $v); b=$(maxver "$rtarm" $v)
  [ "$(printf '%s\n%s\n' "$b" "$a" | sort -V | tail -1)" = "$a" ] ||
    fail "arm64 programs need $v$b, newer than amd64's $v$a on which the Depends floors rest"
done
echo "  arm64 programs need $(wc -w <<<"$narm") shared libraries, all needed on amd64 too; no newer symbol versions on arm64"

# ---- 4. Install into scratch roots ----------------------------------------------------------
install_root() {  # root debs...
  local root=$1; shift
  mkdir -p "$root/var/lib/dpkg/info" "$root/var/lib/dpkg/updates"
  : > "$root/var/lib/dpkg/status"
  dpkg --root="$root" --force-not-root --force-depends --force-architecture -i "$@" >/dev/null
  dpkg --root="$root" -s zonemap libzonemap-dev | grep -q "Status: install ok installed" ||
    fail "dpkg did not install into $root"
}
step "dpkg --root: amd64 and arm64 into scratch roots"
root64=$work/root-amd64; rootarm=$work/root-arm64
install_root "$root64" "$rt64" "$dev64"
install_root "$rootarm" "$rtarm" "$devarm"

# The systemd unit and the drop-in computed from the profile by the core's budget function.
dropin=$root64/usr/lib/systemd/system/zonemapd@orin-nano-8gb.service.d/50-budget.conf
grep -qx "MemoryMax=4274015488" "$dropin" || fail "$dropin: MemoryMax is not the Orin's map share 4274015488"
grep -qx "LimitMEMLOCK=4274015488" "$dropin" || fail "$dropin: LimitMEMLOCK is not 4274015488"
cmp -s "$dropin" "$rootarm/usr/lib/systemd/system/zonemapd@orin-nano-8gb.service.d/50-budget.conf" ||
  fail "the arm64 drop-in (computed under qemu) differs from the amd64 one"
if command -v systemd-analyze >/dev/null && systemd-analyze --help | grep -q -- '--root'; then
  # The scratch root has no systemd of its own, so the default dependencies' targets are
  # missing; anything else it says (an unknown key, a bad value, a missing program) fails.
  out=$(systemd-analyze verify --root="$root64" zonemapd@orin-nano-8gb.service 2>&1) || true
  bad=$(grep -v -e "Unit sysinit.target not found" -e '^$' <<<"$out" || true)
  [ -z "$bad" ] || fail "systemd-analyze verify zonemapd@orin-nano-8gb.service: $bad"
  echo "  systemd-analyze verify zonemapd@orin-nano-8gb.service: no complaints about the unit"
else
  echo "  systemd-analyze (with --root) is not installed: the unit's syntax is not verified (SKIPPED)"
fi

# ---- 5. Run the installed programs ----------------------------------------------------------
step "amd64: installed zonemap --help, sim, zonemapd replay"
"$root64/usr/bin/zonemap" --help >/dev/null
"$root64/usr/bin/zonemapd" --help >/dev/null
# Tiny dense images (--dense 32x24): the replay still decodes JPEG + RVL keyframes into slots,
# in seconds rather than minutes under qemu. 32x24 has no room for ORB: the oracle's features, named.
"$root64/usr/bin/zonemap" sim hospital --seed 3 --area 400 --tasks 3 --dense 32x24 --features oracle --quiet \
  --out "$work/scenario" >/dev/null
check_run() {  # summary.json root
  python3 - "$1" "$2" <<'PY'
import json, os, sys
s = json.load(open(sys.argv[1]))
prof = os.path.normpath(s["profile"])
assert prof.startswith(sys.argv[2] + "/usr/share/zonemap/profiles/"), f"profile read from {prof}, not the installed one"
assert s["ticks"] == 60, s["ticks"]
assert s["peak_resident_keyframes"] <= s["k_max"], (s["peak_resident_keyframes"], s["k_max"])
assert s["over_budget_ticks"] == 0 and s["zone_loads"] >= 1
print(f"  zonemapd: {s['ticks']} ticks, peak resident {s['peak_resident_keyframes']} <= K_max {s['k_max']}, "
      f"{s['zone_loads']} zone loads, profile {prof[len(sys.argv[2]):]}")
PY
}
env -u ZM_PROFILES_DIR "$root64/usr/bin/zonemapd" --profile host --db "$work/scenario/map.db" \
  --frames "$work/scenario/frames.bin" --memory-thr 150 --max-ticks 60 --out "$work/run-amd64" 2>/dev/null
check_run "$work/run-amd64/summary.json" "$root64"

step "arm64 (qemu): installed zonemap --help, zonemapd replay"
"${qemu[@]}" "$rootarm/usr/bin/zonemap" --help >/dev/null
env -u ZM_PROFILES_DIR "${qemu[@]}" "$rootarm/usr/bin/zonemapd" --profile host --db "$work/scenario/map.db" \
  --frames "$work/scenario/frames.bin" --memory-thr 150 --max-ticks 60 --out "$work/run-arm64" 2>/dev/null
check_run "$work/run-arm64/summary.json" "$rootarm"

# ---- 6. A separate project against the installed package ------------------------------------
step "amd64: examples/embed against the installed CMake package"
cmake -S examples/embed -B "$work/embed-amd64" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$root64/usr" >/dev/null
grep -q "zonemap_DIR:PATH=$root64/usr/lib/x86_64-linux-gnu/cmake/zonemap" "$work/embed-amd64/CMakeCache.txt" ||
  fail "the consumer did not find the installed package"
cmake --build "$work/embed-amd64" >/dev/null
"$work/embed-amd64/zonemap_embed" "$work/scenario" --policy all --work "$work" | sed 's/^/  /'

step "amd64: the same program with pkg-config alone"
pcdir=$root64/usr/lib/x86_64-linux-gnu/pkgconfig
# shellcheck disable=SC2046
g++ -O1 examples/embed/embed.cc -o "$work/embed-pc" \
  $(PKG_CONFIG_PATH=$pcdir pkg-config --static --cflags --libs zonemap)
"$work/embed-pc" "$work/scenario" --policy semantic --ticks 200 --work "$work" | grep -q "embed: ok" ||
  fail "the pkg-config build of examples/embed failed its run"
echo "  pkg-config --static --libs zonemap: $(PKG_CONFIG_PATH=$pcdir pkg-config --static --libs zonemap | cut -c1-80)..."

step "arm64: examples/embed cross-built against the installed arm64 package, run under qemu"
cmake -S examples/embed -B "$work/embed-arm64" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_TOOLCHAIN_FILE="$repo/toolchains/aarch64-linux-gnu.cmake" \
  -Dzonemap_DIR="$rootarm/usr/lib/aarch64-linux-gnu/cmake/zonemap" >/dev/null
cmake --build "$work/embed-arm64" >/dev/null
machine "$work/embed-arm64/zonemap_embed" | grep -q AArch64 || fail "the consumer was not cross-built"
"${qemu[@]}" "$work/embed-arm64/zonemap_embed" "$work/scenario" --policy all --work "$work" | sed 's/^/  /'

step "ok: packages built, installed, run and consumed on amd64 and arm64"
