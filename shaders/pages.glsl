// Storage past one buffer: up to kPages storage buffers at binding 6, each of 2^frame.size.w
// units (ll: nodes, shaders/ll_nodes.glsl; mlab: words, shaders/mlab.glsl), so a frame may need
// more than one buffer can hold (maxStorageBufferRange: 4 GiB on NVIDIA, 128 MiB on lavapipe).
// Pages are reached by constant index, so no descriptor-indexing feature is needed. 16 pages,
// not more: with the 5 other storage buffers of the set they stay within Mesa gallium's 32
// shader buffers per stage (lavapipe crashes past it). Define PAGES_QUALIFIER (coherent) before
// including where other invocations' writes must be seen. Needs frame.glsl.

#ifndef PAGES_QUALIFIER
#define PAGES_QUALIFIER
#endif

const uint kPages = 16u;
// Specialisation constant 2: whether the pool spans more than one page. Off, every access goes
// straight to page 0, as fast as a single buffer (the switch below cost 40 % of ll's gather and
// doubled mlab's insert on an H100).
layout(constant_id = 2) const bool kPaged = false;
layout(set = 0, binding = 6, std430) PAGES_QUALIFIER buffer Pages { uint v[]; } pages[kPages];

#define LOAD(n) case n: return pages[n].v[i];
uint page_load(uint page, uint i) {
  if (!kPaged) return pages[0].v[i];
  switch (page) {
    LOAD(0) LOAD(1) LOAD(2) LOAD(3) LOAD(4) LOAD(5) LOAD(6) LOAD(7)
    LOAD(8) LOAD(9) LOAD(10) LOAD(11) LOAD(12) LOAD(13) LOAD(14)
    default: return pages[15].v[i];
  }
}
#undef LOAD

#define STORE(n) case n: pages[n].v[i] = word; break;
void page_store(uint page, uint i, uint word) {
  if (!kPaged) {
    pages[0].v[i] = word;
    return;
  }
  switch (page) {
    STORE(0) STORE(1) STORE(2) STORE(3) STORE(4) STORE(5) STORE(6) STORE(7)
    STORE(8) STORE(9) STORE(10) STORE(11) STORE(12) STORE(13) STORE(14)
    default: pages[15].v[i] = word; break;
  }
}
#undef STORE

// Unit `u` is at page u >> shift, index u & mask: a power of two per page spares a division.
uint page_of(uint u) {
  return kPaged ? u >> frame.size.w : 0u;
}

uint index_in_page(uint u) {
  return kPaged ? u & ((1u << frame.size.w) - 1u) : u;
}

// Word `w` of a pool of words (mlab).
uint word_load(uint w) {
  return page_load(page_of(w), index_in_page(w));
}

void word_store(uint w, uint word) {
  page_store(page_of(w), index_in_page(w), word);
}
