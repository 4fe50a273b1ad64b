#!/usr/bin/env bash
# scripts/bench-gpu, the GPU measurements in one command, at a tiny scale on lavapipe: every
# (set, technique) row in render-SET.json with its figures, summary.md's times and ratios equal
# to what the JSON holds (read here on their own, not through the summary's code), the tests
# step's results, caches kept for a second run at the same scale and baked again at another,
# --steps, bad arguments refused before any work, and the compiler statistics written where a
# driver reports them (RADV compiling for an AMD GPU that is not there).
set -u
bin="$1" repo="$2" tests="$3"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; [ -f "$tmp/out/log.txt" ] && tail -20 "$tmp/out/log.txt"; exit 1; }
bench=("$repo/scripts/bench-gpu" --linebake "$bin" --tests "$tests" --out "$tmp/out"
  --data "$tmp/data" --size 64x48 --frames 2)

# The tests step here on two quick sort tests, which pass.
"${bench[@]}" --scale 0.002 --sets aneurysm,convection --techniques tiles,ll,tiles-triangles \
  --tests-filter 'RadixSort.EmptyAndSingle:RadixSort.LowBitsOnly' > "$tmp/run1.txt" 2>&1 ||
  { cat "$tmp/run1.txt"; fail "first run"; }
[ "$(cut -d' ' -f1,2 "$tmp/out/tests.txt" | tr '\n' ' ')" = \
  "passed RadixSort.EmptyAndSingle passed RadixSort.LowBitsOnly " ] || fail "tests.txt: $(cat "$tmp/out/tests.txt")"
for f in machine.txt render-aneurysm.json render-convection.json summary.md log.txt tests.txt; do
  [ -s "$tmp/out/$f" ] || fail "no $f"
done
for f in aneurysm.lbc.h5 convection.lbc.h5; do
  [ -s "$tmp/data/$f" ] && [ ! -e "$tmp/out/$f" ] || fail "$f is not in --data alone"
done
ls "$tmp/out" "$tmp/data" | grep -q '\.tmp$' && fail "a temporary file was left"
# lavapipe reports no compiler statistics: the reason is kept, the run goes on.
[ -s "$tmp/out/shaders.txt" ] && [ ! -e "$tmp/out/shaders.json" ] || fail "shaders.txt on lavapipe"
grep -q "VK_KHR_pipeline_executable_properties" "$tmp/out/shaders.txt" || fail "shaders.txt: why"
grep -q "^command: scale 0.002, sets aneurysm,convection" "$tmp/out/machine.txt" || fail "machine.txt"

# q EXPR FILE: EXPR of the JSON `r` in FILE, in Python; render SET: the set's bench JSON.
q() { python3 -c "import json, sys; r = json.load(open(sys.argv[2])); print($1)" "$1" "$2"; }
render() { echo "$tmp/out/render-$1.json"; }
for set in aneurysm convection; do
  [ "$(q "[run['cache'] for run in r['runs']]" "$(render $set)")" = "['$set']" ] || fail "render-$set.json's set"
  [ "$(q "r['size'], r['frames'], r['warm_up']" "$(render $set)")" = "[64, 48] 2 1" ] || fail "size, frames"
  rows=$(q "sum(1 for run in r['runs'] for row in run['rows'] if row['gpu_ms']['median'] > 0 and row['psnr_db'] > 0)" "$(render $set)")
  [ "$rows" = 3 ] || fail "render-$set.json: $rows rows with figures, 3 expected"
done
gpu() { q "[row['gpu_ms']['$3'] for run in r['runs'] for row in run['rows'] if row['technique'] == '$2'][0]" "$(render "$1")"; }
# cell N SET COLUMN: the cell of summary.md's Nth table in SET's row, under COLUMN's header
# (the Markdown read here on its own).
cell() {
  python3 - "$tmp/out/summary.md" "$@" << 'EOF'
import sys
path, n, wanted_set, column = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
tables, rows = [], None
for line in open(path, encoding="utf-8").read().splitlines():
    if not line.startswith("|"):
        rows = None
        continue
    if rows is None:
        rows = []
        tables.append(rows)
    rows.append([c.strip() for c in line.strip("|").split("|")])
header, *body = tables[n - 1]
print(next(r for r in body[1:] if r[0].split(" (")[0] == wanted_set)[header.index(column)])
EOF
}
# Every GPU time (median and max) in its column, and every ratio of ll's time to another's.
for set in aneurysm convection; do
  for t in tiles ll tiles-triangles; do
    want=$(awk -v a="$(gpu "$set" "$t" median)" -v b="$(gpu "$set" "$t" max)" 'BEGIN { printf "%.1f (%.1f)", a, b }')
    got=$(cell 1 "$set" "\`$t\`")
    [ "$got" = "$want" ] || fail "summary.md: $set $t: '$got', not '$want'"
  done
  for t in tiles tiles-triangles; do
    want=$(awk -v a="$(gpu "$set" ll median)" -v b="$(gpu "$set" "$t" median)" 'BEGIN { printf "%.2f", a / b }')
    got=$(cell 2 "$set" "\`$t\`")
    [ "$got" = "$want" ] || fail "summary.md: ll / $t on $set: '$got', not '$want'"
  done
done
# A tiles row carries its keys and walks; ll's row none.
grep -q "^| aneurysm | \`tiles\` | bin .*(median), 1, " "$tmp/out/summary.md" || fail "tiles' keys"
[ "$(awk -F'|' '$2 ~ /aneurysm/ && $3 ~ /`ll`/ { gsub(/ /, "", $7); print "[" $7 "]" }' "$tmp/out/summary.md")" = "[]" ] ||
  fail "ll's row has tiles' figures"

# The same scale again: the caches are kept; --steps render alone renders them. Late shading's
# row notes the hits its second test missed (none here); tiles' row says nothing of them.
"${bench[@]}" --scale 0.002 --sets aneurysm,convection --techniques tiles,tiles-late-shading \
  --steps data,render > "$tmp/run2.txt" 2>&1 || fail "second run"
grep -q "baking" "$tmp/run2.txt" && fail "the second run baked again"
for set in aneurysm convection; do
  [ "$(q "sum(len(run['rows']) for run in r['runs'])" "$(render $set)")" = 2 ] || fail "second run's rows"
  [ "$(awk -F'|' -v s="$set" '$2 ~ s && $3 ~ /`tiles-late-shading`/ { gsub(/^ +| +$/, "", $8); print $8 }' "$tmp/out/summary.md")" = "late misses 0" ] ||
    fail "summary.md: $set's late-shading note"
  awk -F'|' -v s="$set" '$2 ~ s && $3 ~ /`tiles`/ && $8 ~ /late/' "$tmp/out/summary.md" | grep -q . &&
    fail "summary.md: $set's tiles row notes late misses"
done
# Another scale: baked again (its segments differ).
"${bench[@]}" --scale 0.004 --sets aneurysm --techniques tiles --steps data > "$tmp/run3.txt" 2>&1 ||
  fail "third run"
grep -q "baking aneurysm at scale 0.004" "$tmp/run3.txt" || fail "another scale was not baked again"
segments=$("$bin" info "$tmp/data/aneurysm.lbc.h5" | awk '$1 == "segments" { print $2 }')
[ "$segments" -gt 4600 ] || fail "the cache at scale 0.004 has $segments segments"
# The render step needs its caches.
rm "$tmp/data/convection.lbc.h5"
"${bench[@]}" --sets aneurysm,convection --steps render > "$tmp/run4.txt" 2>&1 && fail "render without a cache"
grep -q "convection.lbc.h5 is missing" "$tmp/run4.txt" || fail "the missing cache is not named"

# A failing test: in tests.txt and the exit status, after the others ran (a stand-in for the
# GoogleTest binary: its list, and one test that fails).
cat > "$tmp/fake_tests" << 'EOF'
#!/usr/bin/env bash
case "$1" in
  --gtest_list_tests) printf 'Running main()\nTiles.\n  Fails\n  Passes  # a comment\n' ;;
  --gtest_filter=Tiles.Fails) echo "the failure's output"; exit 1 ;;
esac
EOF
chmod +x "$tmp/fake_tests"
"$repo/scripts/bench-gpu" --linebake "$bin" --tests "$tmp/fake_tests" --out "$tmp/out" --steps tests \
  > "$tmp/run5.txt" 2>&1
rc=$?
[ "$rc" = 1 ] || fail "a failed test: exit $rc"
[ "$(cut -d' ' -f1,2 "$tmp/out/tests.txt" | tr '\n' ' ')" = "failed Tiles.Fails passed Tiles.Passes " ] ||
  fail "tests.txt: $(cat "$tmp/out/tests.txt")"
grep -q "1 passed, 1 failed" "$tmp/run5.txt" && grep -q "the failure's output" "$tmp/out/log.txt" ||
  fail "the failed test is not reported"

# Bad arguments: exit 2 before any work.
while IFS='|' read -r args why; do
  # shellcheck disable=SC2086
  "$repo/scripts/bench-gpu" --linebake "$bin" --out "$tmp/bad" $args > "$tmp/bad.txt" 2>&1
  rc=$?
  [ "$rc" = 2 ] || fail "'$args' exited $rc"
  grep -qF -e "$why" "$tmp/bad.txt" || fail "'$args' did not say '$why': $(cat "$tmp/bad.txt")"
  [ -e "$tmp/bad" ] && fail "'$args' wrote $tmp/bad"
done << 'EOF'
--bogus|unknown argument '--bogus'
--out|--out needs a value
--steps fly|unknown step 'fly'
--tests /nonexistent|no test binary at /nonexistent
--linebake /nonexistent|no linebake at /nonexistent
EOF

# A set that fails to bake: said, the others baked and rendered, exit 1; a test filter that
# matches nothing: exit 1.
"${bench[@]}" --scale 0.002 --sets nosuchset,aneurysm --techniques tiles --steps data,render \
  > "$tmp/run7.txt" 2>&1
rc=$?
[ "$rc" = 1 ] || fail "a failed bake: exit $rc"
grep -q "baking nosuchset failed" "$tmp/run7.txt" && grep -q "render-aneurysm.json in" "$tmp/run7.txt" ||
  fail "a failed bake stopped the run: $(cat "$tmp/run7.txt")"
# A run split by set: the summary is of every set rendered into DIR, the aneurysm's from above.
"${bench[@]}" --scale 0.002 --sets convection --techniques tiles --steps data,render \
  > "$tmp/run9.txt" 2>&1 || fail "convection alone"
grep -q "^| aneurysm (" "$tmp/out/summary.md" && grep -q "^| convection (" "$tmp/out/summary.md" ||
  fail "the summary lost the set of an earlier call"
"${bench[@]}" --steps tests --tests-filter 'NoSuchSuite.*' > "$tmp/run8.txt" 2>&1
rc=$?
[ "$rc" = 1 ] && grep -q "no test matches NoSuchSuite" "$tmp/run8.txt" || fail "an empty filter: exit $rc"

# Where the driver reports compiler statistics, shaders.json has them.
radv=/usr/share/vulkan/icd.d/radeon_icd.x86_64.json
if [ -f "$radv" ]; then
  VK_ICD_FILENAMES="$radv" RADV_FORCE_FAMILY=navi21 \
    "${bench[@]}" --sets aneurysm --scale 0.004 --steps shaders > "$tmp/run6.txt" 2>&1 || fail "shaders on RADV"
  [ -s "$tmp/out/shaders.json" ] && [ ! -e "$tmp/out/shaders.txt" ] || fail "shaders.json on RADV"
  [ "$(q "any('tiles_composite' in s['shader'] for s in r['shaders'])" "$tmp/out/shaders.json")" = True ] ||
    fail "shaders.json has no tiles_composite"
fi
echo "bench-gpu: ok"
