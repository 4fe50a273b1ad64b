#!/usr/bin/env bash
# Exports a plain, a --lines and a Draco .glb (COLOR_0, TEXCOORD_0, indexed LINES: the defaults)
# and a .gltf with its .bin and --line-strips from a small synthetic data set and checks each with
# the Khronos glTF-Validator: zero errors.
set -u
bin=$1 node_modules=$2
here=$(cd "$(dirname "$0")" && pwd)
if [ ! -f "$node_modules/gltf-validator/package.json" ]; then
  echo "gltf-validator is not installed in $node_modules (run scripts/setup)"
  exit 1
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
set -e
"$bin" bake "synth:aneurysm?scale=0.01" -o "$tmp/a.lbc.h5" --caps > /dev/null
"$bin" export "$tmp/a.lbc.h5" --glb "$tmp/plain.glb"
"$bin" export "$tmp/a.lbc.h5" --glb "$tmp/lines.glb" --lines
"$bin" bake "synth:aneurysm?scale=0.01" -o "$tmp/o.lbc.h5" --normals oct16 --chunk-bytes 200000 > /dev/null
"$bin" export "$tmp/o.lbc.h5" --glb "$tmp/chunks.glb" --no-tubes --lines
"$bin" export "$tmp/o.lbc.h5" --glb "$tmp/draco.glb" --draco
"$bin" export "$tmp/o.lbc.h5" -o "$tmp/strips.gltf" --lines --line-strips --axes raw --colors none
node "$here/gltf_validate.mjs" "$node_modules" "$tmp/plain.glb" "$tmp/lines.glb" "$tmp/chunks.glb" \
  "$tmp/draco.glb" "$tmp/strips.gltf"
