#!/usr/bin/env bash
# Checks (and, as root with apt-get, installs) what servoface needs beyond Python:
# EGL + Mesa llvmpipe for headless rendering of the twin, and Chromium for the studio's browser tests.
set -u

# Chromium (Debian's package) for the studio's browser tests (Playwright drives it; it never downloads a
# browser). Optional: without it those tests skip and say why, everything else works.
if ! command -v chromium >/dev/null 2>&1 && ! command -v chromium-browser >/dev/null 2>&1; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
    echo "servoface: installing Debian's chromium (the studio's browser tests) with apt-get (root) ..."
    if ! (DEBIAN_FRONTEND=noninteractive apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null); then
      echo "servoface: could not install chromium with apt-get; the studio's browser tests will skip" \
        "(install it by hand: sudo apt-get install chromium)" >&2
    fi
  else
    echo "servoface: no chromium found; the studio's browser tests will skip (sudo apt-get install chromium)" >&2
  fi
fi

need=()
have_lib() { ldconfig -p 2>/dev/null | grep -q "$1"; }
have_lib 'libEGL.so.1' || need+=(libegl1)
have_lib 'libGL.so.1' || need+=(libgl1)
have_lib 'libOpenGL.so.0' || need+=(libopengl0)
compgen -G '/usr/share/glvnd/egl_vendor.d/*mesa*' >/dev/null || need+=(libegl-mesa0)
compgen -G '/usr/lib/*/dri/swrast_dri.so' >/dev/null || compgen -G '/usr/lib/*/dri/kms_swrast_dri.so' >/dev/null \
  || compgen -G '/usr/lib/dri/swrast_dri.so' >/dev/null || need+=(libgl1-mesa-dri)
if [ ${#need[@]} -eq 0 ]; then
  exit 0
fi
echo "servoface: headless rendering needs the Debian packages: ${need[*]}"
if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
  echo "servoface: installing them with apt-get (root) ..."
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq && apt-get install -y -qq "${need[@]}" >/dev/null && exit 0
  echo "servoface: apt-get failed; install them by hand: sudo apt-get install ${need[*]}" >&2
  exit 1
fi
echo "servoface: please run: sudo apt-get install ${need[*]}   (then run make again)" >&2
exit 1
