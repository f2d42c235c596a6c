#!/usr/bin/env bash
# tests/ha/install.sh: Home Assistant core in its own venv, tests/ha/.venv
# (git-ignored), for tests/mqtt/home_assistant.rs. ./test.sh runs it when
# tests/ha/.venv/complete is missing; the shared .venv is left alone.
#
# Home Assistant 2024.3.x is the last release for Python 3.11. Its wheel
# ships homeassistant/package_constraints.txt, the pins its own releases are
# tested with: installing under those constraints lets pip take binary wheels
# instead of backtracking through source builds (a plain `pip install
# homeassistant==2024.3.3` ends in ResolutionImpossible on habluetooth).
# The extra requirements are those of the integrations the test loads
# (their manifest.json "requirements"): mqtt (paho-mqtt), file_upload
# (janus, an mqtt dependency), image_upload (Pillow, through onboarding's
# person), recorder (SQLAlchemy, fnv-hash-fast: analytics imports it) and
# the integrations Home Assistant always loads (bootstrap.py's
# DEFAULT_INTEGRATIONS: frontend, backup's securetar, hardware's
# psutil-home-assistant; without the frontend it falls into recovery mode).
# josepy: the constraints leave it free and josepy 2 dropped what acme 2.8
# (hass-nabucasa's, imported by http's forwarded middleware) uses.
# The test runs hass with --skip-pip, so nothing is fetched then.
set -euo pipefail
cd "$(dirname "$0")"
version=2024.3.3
extra=(paho-mqtt==1.6.1 janus==1.0.0 Pillow==10.2.0 home-assistant-frontend==20240307.0
  securetar==2024.2.1 psutil-home-assistant==0.0.1 SQLAlchemy==2.0.27 fnv-hash-fast==0.5.0
  josepy==1.14.0)

python3 -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' || {
  echo "tests/ha/install.sh: Home Assistant $version needs Python 3.11, this is $(python3 --version)" >&2
  exit 1
}
# A venv's scripts name its own path, so it is made in place; the marker
# file .venv/complete, written last, says the install finished.
rm -rf .venv
python3 -m venv .venv
pip=(.venv/bin/pip --disable-pip-version-check --quiet)
"${pip[@]}" install --upgrade pip wheel
download=$(mktemp -d)
trap 'rm -rf "$download"' EXIT
"${pip[@]}" download --no-deps --dest "$download" "homeassistant==$version"
python3 -c 'import sys, zipfile; sys.stdout.buffer.write(zipfile.ZipFile(sys.argv[1]).read("homeassistant/package_constraints.txt"))' \
  "$download"/homeassistant-"$version"-py3-none-any.whl >"$download/constraints.txt"
"${pip[@]}" install --prefer-binary -c "$download/constraints.txt" \
  "$download"/homeassistant-"$version"-py3-none-any.whl "${extra[@]}"
.venv/bin/hass --version
echo "$version" >.venv/complete
