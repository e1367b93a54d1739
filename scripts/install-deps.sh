#!/usr/bin/env bash
# Installs every build, test and cross-build dependency from Debian packages.
# Idempotent: what is already there is not fetched again, so `make test` and `make demo`
# call this on every run and it then costs a few dpkg queries.
#
#   scripts/install-deps.sh            host packages + the aarch64 cross toolchain and sysroot
#   scripts/install-deps.sh --host     host packages only
#   ... --probes                       also python3-torch, for scripts/image_cue_probe.py (a
#                                      development probe; no build, test or demo needs it)
#
# Why an arm64 sysroot instead of `apt-get install libopencv-dev:arm64`: on Debian 12 the two
# architectures of libopencv-dev Conflict with each other, and libopencv-imgcodecs406:arm64
# needs libgdal32:arm64, which is not co-installable with the host's libgdal32. So the arm64
# side (the exact closure of libopencv-dev:arm64 and our other libraries, resolved by apt for
# arch arm64 against an empty dpkg status) is downloaded from Debian's arm64 archive and
# unpacked into ZM_ARM64_SYSROOT. The cross toolchain builds against it with --sysroot and
# qemu-aarch64 runs the tests with -L pointing at it: the same shape as the Jetson toolchain,
# whose sysroot is a JetPack root filesystem.
set -euo pipefail

want_arm64=1
want_probes=0
for a in "$@"; do
  case "$a" in
    --host) want_arm64=0 ;;
    --probes) want_probes=1 ;;
    *) echo "install-deps.sh: unknown option '$a' (known: --host, --probes)" >&2; exit 2 ;;
  esac
done

SYSROOT=${ZM_ARM64_SYSROOT:-/opt/zonemap/sysroot-arm64}

host_pkgs=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev libopencv-dev libsqlite3-dev sqlite3 libmimalloc-dev
  doctest-dev libbenchmark-dev nlohmann-json3-dev libtomlplusplus-dev libcli11-dev
  zlib1g-dev libjpeg-dev libpng-dev python3 python3-matplotlib python3-numpy
  # scripts/train_layout_merge.py fits the layout merge model (tests/scripts runs it);
  # scripts/render_r2v.py and render_sim.py draw the training and held-out grids.
  python3-sklearn python3-pil
  # Clang builds the host's ASan + UBSan tests (host-debug: in about 55 % of GCC's CPU time) and
  # the libFuzzer targets; lld links them, llvm-symbolizer names the frames of a sanitizer report.
  clang-14 libclang-rt-14-dev lld-14 llvm-14
)
cross_pkgs=(g++-aarch64-linux-gnu qemu-user)
# The arm64 libraries that go into the sysroot (apt adds their whole dependency closure).
arm64_pkgs=(
  libc6-dev libstdc++-12-dev libopencv-dev libsqlite3-dev libmimalloc-dev zlib1g-dev libjpeg-dev
  libpng-dev
  libeigen3-dev doctest-dev nlohmann-json3-dev libtomlplusplus-dev libcli11-dev
)

as_root=()
if [ "$(id -u)" -ne 0 ]; then as_root=(sudo); fi
export DEBIAN_FRONTEND=noninteractive

missing() {
  local out=()
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || out+=("$p")
  done
  echo "${out[@]:-}"
}

pkgs=("${host_pkgs[@]}")
if [ "$want_arm64" = 1 ]; then pkgs+=("${cross_pkgs[@]}"); fi
if [ "$want_probes" = 1 ]; then pkgs+=(python3-torch); fi
updated=0
todo=$(missing "${pkgs[@]}")
if [ -n "$todo" ]; then
  echo "install-deps: installing $todo"
  "${as_root[@]}" apt-get update -qq
  updated=1
  # shellcheck disable=SC2086
  "${as_root[@]}" apt-get install -y -qq --no-install-recommends $todo >/dev/null
fi

if [ "$want_arm64" = 1 ]; then
  stamp="$SYSROOT/.zonemap-sysroot"
  want_stamp="${arm64_pkgs[*]}"
  if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want_stamp" ]; then
    echo "install-deps: building the arm64 sysroot in $SYSROOT"
    if ! dpkg --print-foreign-architectures | grep -qx arm64; then
      "${as_root[@]}" dpkg --add-architecture arm64
      updated=0
    fi
    if [ "$updated" = 0 ]; then "${as_root[@]}" apt-get update -qq; fi
    work=$(mktemp -d)
    trap 'rm -rf "$work"' EXIT
    mkdir -p "$work/archives/partial"
    : > "$work/status"
    # An empty dpkg status makes apt resolve the full arm64 closure, libc included.
    apt-get -qq -y -o APT::Architecture=arm64 -o APT::Architectures=arm64 \
      -o Dir::State::status="$work/status" -o Dir::Cache::archives="$work/archives" \
      -o Debug::NoLocking=1 --download-only install "${arm64_pkgs[@]}" >/dev/null
    "${as_root[@]}" rm -rf "$SYSROOT.new"
    "${as_root[@]}" mkdir -p "$SYSROOT.new"
    for deb in "$work"/archives/*.deb; do "${as_root[@]}" dpkg-deb -x "$deb" "$SYSROOT.new"; done
    # Debian 12 is usr-merged: the loader and libc ship under /lib, which the system maps to
    # /usr/lib. Mirror that so the loader's default search paths work under qemu -L.
    for d in lib lib64; do
      if [ -d "$SYSROOT.new/$d" ] && [ ! -L "$SYSROOT.new/$d" ]; then
        "${as_root[@]}" cp -a "$SYSROOT.new/$d/." "$SYSROOT.new/usr/$d/"
        "${as_root[@]}" rm -rf "$SYSROOT.new/$d"
        "${as_root[@]}" ln -s "usr/$d" "$SYSROOT.new/$d"
      fi
    done
    # update-alternatives normally links the reference BLAS/LAPACK into the multiarch directory
    # from the packages' postinst scripts, which dpkg-deb -x does not run; OpenCV needs them.
    multi="$SYSROOT.new/usr/lib/aarch64-linux-gnu"
    for alt in blas lapack; do
      for so in "$multi/$alt"/lib*.so.3; do
        [ -e "$so" ] && [ ! -e "$multi/$(basename "$so")" ] && "${as_root[@]}" ln -s "$alt/$(basename "$so")" "$multi/$(basename "$so")"
      done
    done
    echo "$want_stamp" | "${as_root[@]}" tee "$SYSROOT.new/.zonemap-sysroot" >/dev/null
    "${as_root[@]}" rm -rf "$SYSROOT"
    "${as_root[@]}" mv "$SYSROOT.new" "$SYSROOT"
    echo "install-deps: arm64 sysroot ready ($(du -sh "$SYSROOT" | cut -f1))"
  fi
fi
echo "install-deps: all dependencies present"
