#!/usr/bin/env bash
# Rebuild src/pinchmatch/viewer/three.bundle.min.js, the copy of three.js that the viewer page inlines.
# One IIFE (global PM3 = {THREE, GLTFLoader, OrbitControls}) so that index.html works from file://
# with nothing loaded from the internet. Needs node and npm; run from the repository root.
set -euo pipefail
THREE_VERSION=0.187.0
ESBUILD_VERSION=0.28.2
root=$(pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
npm init -y >/dev/null
npm install --silent --no-audit --no-fund "three@$THREE_VERSION" "esbuild@$ESBUILD_VERSION"
cat > entry.js <<'JS'
export * as THREE from 'three';
export { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
export { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
JS
npx esbuild entry.js --bundle --minify --format=iife --global-name=PM3 --legal-comments=none \
    --outfile="$root/src/pinchmatch/viewer/three.bundle.min.js"
cp node_modules/three/LICENSE "$root/src/pinchmatch/viewer/THREE_LICENSE"
echo "three.js $THREE_VERSION bundled into src/pinchmatch/viewer/three.bundle.min.js"
