// The primitives' two arrays, in pages past one storage buffer: binding 1 holds vec4 units (the
// capsules' points; the triangles' vertices, two units each) and binding 2 uint words (the
// capsules' segment words; the triangles' indices). Where one array does not fit one storage
// buffer (128 MiB on lavapipe, 4 GiB on NVIDIA), specialisation constant 0 is set and it goes in
// pages of 2^kUnitShift units and 2^kWordShift words: page 0 at binding 1 or 2, the rest at
// bindings 19 and 20, reached by constant index as shaders/pages.glsl does (no
// descriptor-indexing feature needed). Off, every access goes straight to bindings 1 and 2.

layout(set = 0, binding = 1, std430) readonly buffer Units { vec4 first_units[]; };
layout(set = 0, binding = 2, std430) readonly buffer Words { uint first_words[]; };

layout(constant_id = 0) const bool kPagedPrimitives = false;
layout(constant_id = 1) const uint kUnitShift = 31u;
layout(constant_id = 2) const uint kWordShift = 31u;
const uint kUnitPages = 8u, kWordPages = 4u;  // TileRenderer's kUnitPages, kWordPages
layout(set = 0, binding = 19, std430) readonly buffer UnitPages { vec4 v[]; }
unit_pages[kUnitPages - 1u];
layout(set = 0, binding = 20, std430) readonly buffer WordPages { uint v[]; }
word_pages[kWordPages - 1u];

#define UNIT(n) case n: return unit_pages[n - 1].v[j];
vec4 unit_at(uint i) {
  if (!kPagedPrimitives) return first_units[i];
  const uint j = i & ((1u << kUnitShift) - 1u);
  switch (i >> kUnitShift) {
    case 0: return first_units[j];
    UNIT(1) UNIT(2) UNIT(3) UNIT(4) UNIT(5) UNIT(6)
    default: return unit_pages[6].v[j];
  }
}
#undef UNIT

#define WORD(n) case n: return word_pages[n - 1].v[j];
uint word_at(uint i) {
  if (!kPagedPrimitives) return first_words[i];
  const uint j = i & ((1u << kWordShift) - 1u);
  switch (i >> kWordShift) {
    case 0: return first_words[j];
    WORD(1) WORD(2)
    default: return word_pages[2].v[j];
  }
}
#undef WORD
