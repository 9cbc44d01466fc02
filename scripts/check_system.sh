#!/usr/bin/env bash
# Checks (and, as root with apt-get, installs) what servoface needs beyond Python:
# EGL + Mesa llvmpipe for headless rendering of the twin.
set -u
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
