#!/bin/sh
# ldconfig.sh - run by `meson install` (lib/meson.build): after an install to the live system
# as root, refresh ld.so's cache so that programs find libsdf and libsdfclient in the new
# library directory at once. A staged install (DESTDIR) or one by another user has no cache
# of its own to refresh.
[ -z "${DESTDIR:-}" ] || exit 0
[ "$(id -u)" -eq 0 ] || exit 0
command -v ldconfig >/dev/null 2>&1 || [ -x /sbin/ldconfig ] || exit 0
PATH="$PATH:/sbin:/usr/sbin" ldconfig
