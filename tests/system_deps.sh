#!/usr/bin/env bash
# Install the system tools the tests need, when running as root and they are absent (called by `make test`).
#
#   chronyd   a real NTP server for tests/unit/common/test_clock.py. It is NOT installed as a package (that
#             would start a system service): `apt-get download chrony` + `dpkg-deb -x` unpack it into
#             .venv/sys/, and the test starts it unprivileged on a high loopback port.
#   ip        (iproute2) and openssl: installed with apt-get when missing (TLS certificates, network tests).
#
# Not root, or no apt-get: say what is missing and carry on; tests then skip (or fail under CI=true).
set -uo pipefail
cd "$(dirname "$0")/.."

SYS_DIR=".venv/sys"
log() { echo "system_deps: $*" >&2; }

have_chronyd() {
    command -v chronyd >/dev/null 2>&1 || [ -x /usr/sbin/chronyd ] || [ -x "$SYS_DIR/usr/sbin/chronyd" ]
}

if [ "$(id -u)" -ne 0 ] || ! command -v apt-get >/dev/null 2>&1; then
    have_chronyd || log "chronyd missing (not root or no apt-get): the real-NTP clock test will skip (fail under CI=true)"
    command -v ip >/dev/null 2>&1 || log "ip (iproute2) missing"
    command -v openssl >/dev/null 2>&1 || log "openssl missing"
    exit 0
fi

export DEBIAN_FRONTEND=noninteractive
updated=0
apt_update() {
    if [ "$updated" -eq 0 ]; then
        log "apt-get update"
        apt-get update -qq >/dev/null 2>&1 || log "apt-get update failed"
        updated=1
    fi
}

# Package names (apt-get install) for missing commands.
missing=()
command -v ip >/dev/null 2>&1 || missing+=(iproute2)
command -v openssl >/dev/null 2>&1 || missing+=(openssl)
if [ "${#missing[@]}" -gt 0 ]; then
    log "installing ${missing[*]}"
    if ! apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null 2>&1; then
        apt_update
        apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null || log "could not install ${missing[*]}"
    fi
fi

# chronyd and the shared libraries it needs, unpacked (never installed) into .venv/sys.
if ! have_chronyd; then
    mkdir -p "$SYS_DIR"
    work="$(mktemp -d)"
    trap 'rm -rf "$work"' EXIT
    (
        cd "$work" || exit 1
        apt-get download chrony >/dev/null 2>&1 || { apt_update; apt-get download chrony >/dev/null; }
    ) || log "could not download chrony"
    for deb in "$work"/chrony_*.deb; do
        [ -f "$deb" ] && dpkg-deb -x "$deb" "$SYS_DIR"
    done
    if [ -x "$SYS_DIR/usr/sbin/chronyd" ]; then
        # chronyd's libraries (libcap2 libedit2 libgnutls30 libnettle8 libseccomp2) are in every Debian 12 base image.
        libs_missing="$(ldd "$SYS_DIR/usr/sbin/chronyd" 2>/dev/null | awk '/not found/ {print $1}' | tr '\n' ' ')"
        [ -n "$libs_missing" ] && log "chronyd needs libraries this system lacks: $libs_missing"
        log "chronyd unpacked into $SYS_DIR/usr/sbin/chronyd"
    else
        log "chronyd unavailable: the real-NTP clock test will skip (fail under CI=true)"
    fi
fi
exit 0
