#!/usr/bin/env bash
# Fetch the console's pinned browser libraries from the npm registry into src/rsi/web/static/vendor/.
# Nothing is fetched at run time: the copies are committed and installed as package data (pyproject).
# npm checks the tarball against the registry's sha512 integrity; the sha256 of each copied file is checked
# below, so a changed upstream file fails loudly instead of slipping in.
set -euo pipefail
cd "$(dirname "$0")/.."
THREE_VERSION=0.170.0
VENDOR=src/rsi/web/static/vendor
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
(cd "$work" && npm pack --silent "three@${THREE_VERSION}" >/dev/null && tar xzf "three-${THREE_VERSION}.tgz")
cp "$work/package/build/three.module.min.js" "$VENDOR/three.module.min.js"
cp "$work/package/examples/jsm/controls/OrbitControls.js" "$VENDOR/OrbitControls.js"
cp "$work/package/LICENSE" "$VENDOR/three.LICENSE"
(cd "$VENDOR" && sha256sum -c SHA256SUMS)
