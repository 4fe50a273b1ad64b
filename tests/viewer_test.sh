#!/usr/bin/env bash
# The viewer window under Xvfb: a script drives it through two techniques and a transfer-function
# key; its screenshots must be byte-identical to `linebake render` of the same camera, the X
# server's framebuffer must show the same pixels (so the swapchain really presented them), the
# comparison key must report PSNR/SSIM, and bad scripts and a missing display must fail cleanly.
set -u
bin="$1"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; [ -f "$tmp/view.out" ] && sed 's/^/  view: /' "$tmp/view.out" | tail -20; exit 1; }

"$bin" bake "synth:aneurysm?scale=0.02" -o "$tmp/c.lbc.h5" --assets tubes,voxels >/dev/null 2>&1 ||
  fail "bake"
cat > "$tmp/script.txt" <<SCRIPT
# flight frame 3 with the CPU ray tracer, then ll (Vulkan) with the next transfer function
technique embree
frame 3
screenshot $tmp/a.png
hold 4            # the frame stays on screen while the test grabs the X framebuffer
technique ll
key f             # semi -> transparent
screenshot $tmp/b.png
compare
key t             # ll -> mlab
wait 1
technique vrc-gpu
key t             # vrc-gpu -> rtx: here (lavapipe) the status line says why not, vrc-gpu stays
wait 1
key t             # the one after rtx, tiles, where a GPU ray traces too
wait 1
quit
SCRIPT
mkdir -p "$tmp/fb"
xvfb-run -a -s "-screen 0 640x480x24 -fbdir $tmp/fb" \
  "$bin" view "$tmp/c.lbc.h5" --size 320x180 --frame-count 8 --script "$tmp/script.txt" \
  --validation > "$tmp/view.out" 2>&1 &
viewer=$!
for _ in $(seq 1 600); do [ -s "$tmp/a.png" ] && break; sleep 0.1; done
[ -s "$tmp/a.png" ] || fail "no screenshot from the viewer"
sleep 1
cp "$tmp/fb/Xvfb_screen0" "$tmp/screen.xwd" || fail "no Xvfb framebuffer"
wait $viewer || fail "view exited with $?"

"$bin" render "$tmp/c.lbc.h5" --technique embree --frame-count 8 --frame 3 --size 320x180 \
  -o "$tmp/ra.png" 2>/dev/null || fail "render embree"
"$bin" render "$tmp/c.lbc.h5" --technique ll --tf transparent --frame-count 8 --frame 3 \
  --size 320x180 -o "$tmp/rb.png" 2>/dev/null || fail "render ll"
cmp -s "$tmp/a.png" "$tmp/ra.png" || fail "embree screenshot differs from linebake render"
cmp -s "$tmp/b.png" "$tmp/rb.png" || fail "ll screenshot differs from linebake render"
grep -Eq '^compare: ll transparent PSNR [0-9.]+ dB SSIM 0\.9[0-9]+' "$tmp/view.out" ||
  fail "no comparison line"
grep -q '^frame: mlab transparent' "$tmp/view.out" || fail "the t key did not switch to mlab"
grep -q '^view: rtx: ray tracing is not supported on this device' "$tmp/view.out" ||
  grep -q '^frame: rtx transparent' "$tmp/view.out" || fail "rtx neither shown nor refused"
grep -q '^frame: tiles transparent' "$tmp/view.out" || fail "the t key did not go on past rtx to tiles"

# The window (at the screen's origin, no window manager) shows the screenshot's pixels below the
# status line, and the image is not blank.
python3 - "$tmp/screen.xwd" "$tmp/a.png" <<'PY' || fail "the X framebuffer does not show the frame"
import struct, sys, zlib
xwd = open(sys.argv[1], "rb").read()
h = struct.unpack(">25I", xwd[:100])
header, bpp, stride, rmask, gmask, bmask, ncolors = h[0], h[11], h[12], h[14], h[15], h[16], h[19]
assert bpp == 32, bpp
pixels = xwd[header + 12 * ncolors:]
order = "<" if h[7] == 0 else ">"
def shift(mask): return (mask & -mask).bit_length() - 1
def screen(x, y):
    v = struct.unpack_from(order + "I", pixels, y * stride + 4 * x)[0]
    return ((v & rmask) >> shift(rmask), (v & gmask) >> shift(gmask), (v & bmask) >> shift(bmask))
png = open(sys.argv[2], "rb").read()
chunks, pos = {}, 8
while pos < len(png):
    n, kind = struct.unpack(">I4s", png[pos:pos + 8])
    chunks.setdefault(kind, b"")
    chunks[kind] += png[pos + 8:pos + 8 + n]
    pos += 12 + n
w, hgt, depth, colour = struct.unpack(">IIBB", chunks[b"IHDR"][:10])
assert (depth, colour) == (8, 2), (depth, colour)
raw = zlib.decompress(chunks[b"IDAT"])
rows, prev, i = [], bytearray(3 * w), 0
for y in range(hgt):
    f, line = raw[i], bytearray(raw[i + 1:i + 1 + 3 * w]); i += 1 + 3 * w
    for x in range(3 * w):
        a = line[x - 3] if x >= 3 else 0; b = prev[x]; c = prev[x - 3] if x >= 3 else 0
        p = [0, a, b, (a + b) // 2, 0][f]
        if f == 4:
            pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
            p = a if pa <= pb and pa <= pc else b if pb <= pc else c
        line[x] = (line[x] + p) & 255
    rows.append(line); prev = line
same = distinct = 0
colours = set()
for y in range(12, hgt):
    for x in range(w):
        want = tuple(rows[y][3 * x:3 * x + 3])
        same += screen(x, y) == want
        colours.add(want)
total = (hgt - 12) * w
assert same == total, f"{same} of {total} pixels match"
assert len(colours) > 20, f"blank-looking frame: {len(colours)} colours"
PY

# A window grown past --memory-budget: the frame is refused with the figures (once, not per
# frame) and the viewer goes on; shrunk back, it draws the flight's frame as before, the same
# bytes as `linebake render` of it (frame 3: not the orbit camera the viewer starts with).
cat > "$tmp/grow.txt" <<SCRIPT
frame 3
wait 1
screenshot $tmp/g1.png
size 1280 720
wait 3
screenshot $tmp/g2.png
size 320 180
wait 2
screenshot $tmp/g3.png
quit
SCRIPT
xvfb-run -a "$bin" view "$tmp/c.lbc.h5" --technique ll --size 320x180 --frame-count 8 \
  --memory-budget 300M --script "$tmp/grow.txt" > "$tmp/grow.out" 2> "$tmp/grow.err"
rc=$?
[ $rc -eq 0 ] || { cat "$tmp/grow.err"; fail "view exited with $rc after a refused frame"; }
[ "$(grep -c '^view: refused: ll at 1280x720: a 1280x720 ll frame needs about .* more than the memory budget of 300.00 MiB' "$tmp/grow.err")" = 1 ] ||
  { cat "$tmp/grow.err"; fail "the refusal was not reported once"; }
grep -q '^view: no screenshot: the frame was refused' "$tmp/grow.err" || fail "screenshot of a refused frame"
[ ! -e "$tmp/g2.png" ] || fail "a refused frame was written"
grep -q '^frame: ll semi 1280x720' "$tmp/grow.out" && fail "a 1280x720 frame was drawn past the budget"
# Frames drawn after the first screenshot: one before the window grew, the rest once it shrank.
after=$(sed -n '/^screenshot: .*g1.png/,$p' "$tmp/grow.out" | grep -c '^frame: ll semi 320x180')
[ "$after" -ge 3 ] || { cat "$tmp/grow.out"; fail "no frames after the window shrank"; }
"$bin" render "$tmp/c.lbc.h5" --technique ll --frame-count 8 --frame 3 --size 320x180 \
  -o "$tmp/rg.png" 2>/dev/null || fail "render ll 320x180"
cmp -s "$tmp/g1.png" "$tmp/rg.png" && cmp -s "$tmp/g3.png" "$tmp/rg.png" ||
  fail "the frames before and after the refusal differ from linebake render of frame 3"

# Bad scripts name the line; no display is a clear error.
printf 'technique ll\nspin 3\n' > "$tmp/bad.txt"
# (The exit code is the viewer's, kept in a file: xvfb-run's own can be its cleanup's, which
# sometimes fails when the X server is stopped right after it started.)
xvfb-run -a bash -c '"$1" view "$2" --size 64x48 --script "$3" 2> "$4" >/dev/null; echo $? > "$5"' \
  _ "$bin" "$tmp/c.lbc.h5" "$tmp/bad.txt" "$tmp/bad.err" "$tmp/bad.code" 2>/dev/null
[ "$(cat "$tmp/bad.code" 2>/dev/null)" = 2 ] && grep -q "bad.txt: line 2: unknown command 'spin'" "$tmp/bad.err" || { cat "$tmp/bad.err"; fail "bad script"; }
env -u DISPLAY -u WAYLAND_DISPLAY "$bin" view "$tmp/c.lbc.h5" --script "$tmp/script.txt" 2> "$tmp/nodisplay.err" >/dev/null
[ $? -eq 4 ] && grep -q "no display" "$tmp/nodisplay.err" || { cat "$tmp/nodisplay.err"; fail "no display"; }
echo "viewer: all checks passed"
