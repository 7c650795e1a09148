#!/usr/bin/env bash
# Installs photonfarm on a Debian/Ubuntu host: the packages it needs
# (deploy/install-deps.sh), a build (deploy/build.sh), then `cmake --install`
# of photonfarm, photonfarm-worker, the docs, the scenes and the deploy
# recipes to a prefix (cmake/install.cmake says what goes where).
#
# usage: deploy/install.sh [--prefix DIR] [--no-deps] [--systemd]
#   --prefix DIR  where to install (default /usr/local: bin/, share/doc/photonfarm/,
#                 share/photonfarm/); DESTDIR is honoured for packaging
#   --no-deps     do not run install-deps.sh (the packages are there, or you
#                 are not root and installed them another way)
#   --systemd     also set the host up for the systemd units (root only): the
#                 photonfarm user (systemd-sysusers), the units in
#                 /etc/systemd/system with ExecStart under the prefix, and
#                 /etc/photonfarm with example settings (never overwritten);
#                 see docs/cluster.md for the keys and `systemctl enable`
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)

prefix=/usr/local
deps=1
systemd=0
while [ $# -gt 0 ]; do
  case $1 in
    --prefix)
      [ $# -ge 2 ] || { echo "install: --prefix needs a directory" >&2; exit 2; }
      prefix=$2
      shift 2
      ;;
    --prefix=*) prefix=${1#--prefix=}; shift ;;
    --no-deps) deps=0; shift ;;
    --systemd) systemd=1; shift ;;
    -h | --help) sed -n '2,17p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "install: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
case $prefix in
  /*) ;;
  *) prefix=$(pwd)/$prefix ;;
esac

# Root, or sudo for the steps that write outside the user's reach.
as_root=()
if [ "$(id -u)" -ne 0 ] && command -v sudo >/dev/null 2>&1; then
  as_root=(sudo)
fi

if [ "$deps" = 1 ]; then
  "$root/deploy/install-deps.sh"
fi

# The install rules live in cmake/install.cmake; a CMakeLists.txt that does
# not include them yet gets them through CMAKE_PROJECT_INCLUDE.
cmake_args=(-DCMAKE_INSTALL_PREFIX="$prefix")
if ! grep -q 'cmake/install.cmake' "$root/CMakeLists.txt"; then
  cmake_args+=(-DCMAKE_PROJECT_INCLUDE="$root/cmake/install.cmake")
fi
"$root/deploy/build.sh" "${cmake_args[@]}"

# Install as this user when the prefix is writable (or will be created in a
# writable parent), otherwise as root.
target="${DESTDIR:-}$prefix"
probe=$target
while [ ! -e "$probe" ]; do
  probe=$(dirname "$probe")
done
if [ -w "$probe" ]; then
  cmake --install "$root/build" --prefix "$prefix"
else
  "${as_root[@]}" cmake --install "$root/build" --prefix "$prefix"
fi
"$target/bin/photonfarm" --version
"$target/bin/photonfarm-worker" --version
echo "install: photonfarm installed under $target (executables in $target/bin)"

if [ "$systemd" = 0 ]; then
  exit 0
fi

# ---- --systemd --------------------------------------------------------------
if [ "$(id -u)" -ne 0 ]; then
  echo "install: --systemd needs root (it writes /etc/systemd/system and /etc/photonfarm)" >&2
  exit 1
fi
if [ -n "${DESTDIR:-}" ]; then
  echo "install: --systemd and DESTDIR do not mix (package the files under share/photonfarm/deploy/systemd instead)" >&2
  exit 1
fi
units=$root/deploy/systemd

install -D -m 0644 "$units/photonfarm.sysusers.conf" /etc/sysusers.d/photonfarm.conf
if command -v systemd-sysusers >/dev/null 2>&1; then
  systemd-sysusers /etc/sysusers.d/photonfarm.conf
elif ! id photonfarm >/dev/null 2>&1; then
  useradd --system --home-dir /var/lib/photonfarm --no-create-home --shell /usr/sbin/nologin photonfarm
fi

# The units name /usr/local; point them at the prefix actually used.
for u in photonfarm-worker.service photonfarm-coordinator@.service; do
  sed -e "s|/usr/local/bin/|$prefix/bin/|g" -e "s|/usr/local/share/doc/photonfarm|$prefix/share/doc/photonfarm|g" \
    "$units/$u" >"/etc/systemd/system/$u"
  chmod 0644 "/etc/systemd/system/$u"
done

install -d -m 0750 -o root -g photonfarm /etc/photonfarm /etc/photonfarm/jobs
for f in worker.env coordinator.env; do
  dest=/etc/photonfarm/$f
  [ "$f" = coordinator.env ] && dest=/etc/photonfarm/jobs/example.env
  if [ ! -e "$dest" ]; then
    install -m 0640 -o root -g photonfarm "$units/$f.example" "$dest"
    echo "install: wrote $dest (edit it)"
  fi
done

if [ -d /run/systemd/system ]; then
  systemctl daemon-reload
fi
echo "install: units in /etc/systemd/system; next: keys and settings in /etc/photonfarm (docs/cluster.md), then"
echo "         systemctl enable --now photonfarm-worker   (on each worker host)"
