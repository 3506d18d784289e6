#!/usr/bin/env bash
# The Debian packages railcal needs besides Python's: the mingw-w64 cross compiler (the FMUs'
# win64 binaries), the PDF route's libraries (WeasyPrint's Pango and HarfBuzz subsetter, a
# font, and poppler-utils to look at a PDF's pages) and Chromium, which the tests use to look
# at the HTML report as a browser shows it. Installs what is missing when it can (as
# root or with passwordless sudo); otherwise names what is missing and carries on, and the
# features that need it say so when used.
set -u
need=()
command -v x86_64-w64-mingw32-gcc >/dev/null 2>&1 || need+=(gcc-mingw-w64-x86-64 binutils-mingw-w64-x86-64)
command -v chromium >/dev/null 2>&1 || need+=(chromium)
for pkg in libpango-1.0-0 libpangoft2-1.0-0 libharfbuzz-subset0 fonts-dejavu-core poppler-utils; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || need+=("$pkg")
done
[ ${#need[@]} -eq 0 ] && exit 0
if ! command -v apt-get >/dev/null 2>&1; then
    echo "warning: not a Debian system; install these yourself: ${need[*]}" >&2
    exit 0
fi
SUDO=""
if [ "$(id -u)" != 0 ]; then
    if command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
        SUDO="sudo -n"
    else
        echo "warning: not root and no passwordless sudo; missing Debian packages: ${need[*]}" >&2
        exit 0
    fi
fi
($SUDO apt-get update -qq && $SUDO apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null) \
    || echo "warning: could not install ${need[*]}; win64 FMU binaries, PDF reports or the" \
            "report's browser check may be unavailable" >&2
exit 0
