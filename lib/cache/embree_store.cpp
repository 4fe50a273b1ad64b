#include "cache/embree_store.hpp"

#include <algorithm>
#include <cstdio>

#include "core/error.hpp"
#include "core/json_file.hpp"

namespace linebake {

static std::string part_group(size_t i) {
  char name[32];
  std::snprintf(name, sizeof name, "/part_%06zu", i);
  return std::string(kEmbreeGroup) + name;
}

void store_embree(CacheWriter& cache, const StoredCurves& curves, Provenance provenance) {
  cache.create_group(kEmbreeGroup);
  uint64_t disk = 0;
  for (size_t i = 0; i < curves.parts.size(); ++i) {
    const PreparedCurves& p = curves.parts[i];
    const std::string g = part_group(i);
    cache.create_group(g);
    disk += cache.write(g + "/vertices", p.vertices.data(), p.vertices.size() / 4, 4);
    disk += cache.write(g + "/indices", p.indices.data(), p.indices.size());
    if (!p.flags.empty()) disk += cache.write(g + "/flags", p.flags.data(), p.flags.size());
  }
  const nlohmann::json description = {{"geometry", to_string(curves.geometry)},
                                      {"radius", curves.radius},
                                      {"attribute", curves.attribute},
                                      {"parts", curves.parts.size()}};
  cache.write_attribute(kEmbreeGroup, "curves", json_text(description));
  provenance.disk_bytes = disk;
  cache.write_provenance(kEmbreeGroup, provenance);
}

EmbreeStoreWriter::EmbreeStoreWriter(CacheWriter& cache, std::vector<CurvePart> parts,
                                     EmbreeGeometry geometry, float radius, std::string attribute,
                                     CurvePiece piece)
    : cache_(cache),
      parts_(std::move(parts)),
      geometry_(geometry),
      radius_(radius),
      attribute_(std::move(attribute)),
      streams_(parts_.size()) {
  cache.create_group(kEmbreeGroup);
  if (!cache.parallel()) return;
  for (size_t i = 0; i < parts_.size(); ++i) {
    open_part(i);
    if (i < piece.part) continue;
    const bool first = i == piece.part;
    const uint64_t points = first ? piece.points_before : 0;
    const uint64_t segments = first ? piece.segments_before : 0;
    PartStreams& s = streams_[i];
    s.vertices->start_at(geometry_ == EmbreeGeometry::BezierCurve ? 4 * segments : points);
    s.indices->start_at(segments);
    if (s.flags) s.flags->start_at(segments);
  }
  part_ = piece.part;
  line_ = piece.first_line;
  part_points_ = piece.points_before;
  part_segments_ = piece.segments_before;
  open_ = true;
}

void EmbreeStoreWriter::open_part(size_t i) {
  const CurvePart& part = parts_[i];
  const std::string g = part_group(i);
  cache_.create_group(g);
  PartStreams& s = streams_[i];
  // + one zero padding vertex for Embree's 16-byte loads
  s.vertices.emplace(cache_.stream<float>(g + "/vertices", curve_vertices(part, geometry_) + 1, 4));
  s.indices.emplace(cache_.stream<uint32_t>(g + "/indices", part.segments));
  if (geometry_ != EmbreeGeometry::BezierCurve)
    s.flags.emplace(cache_.stream<uint8_t>(g + "/flags", part.segments));
  buffer_bytes_ += (curve_vertices(part, geometry_) + 1) * 16 + part.segments * 4 +
                   (s.flags ? part.segments : 0);
}

uint64_t EmbreeStoreWriter::close_part(size_t i) {
  PartStreams& s = streams_[i];
  const uint64_t disk = s.vertices->close() + s.indices->close() + (s.flags ? s.flags->close() : 0);
  s = PartStreams{};
  return disk;
}

uint64_t EmbreeStoreWriter::segments() const {
  uint64_t n = 0;
  for (const CurvePart& part : parts_) n += part.segments;
  return n;
}

void EmbreeStoreWriter::append(const LineSet& batch) {
  const uint64_t first = line_, end = line_ + batch.line_count();
  while (part_ < parts_.size() && parts_[part_].first_line < end) {
    const CurvePart& part = parts_[part_];
    const uint64_t from = std::max(first, part.first_line), to = std::min(end, part.end_line);
    if (!open_) {
      open_part(part_);
      part_points_ = part_segments_ = 0;
      open_ = true;
    }
    PartStreams& s = streams_[part_];
    const size_t l0 = size_t(from - first), l1 = size_t(to - first);
    const uint64_t points = batch.line_offsets[l1] - batch.line_offsets[l0];
    uint64_t segments = 0;
    for (size_t l = l0; l < l1; ++l)
      segments += batch.line_size(l) > 1 ? batch.line_size(l) - 1 : 0;
    const uint64_t vertices = geometry_ == EmbreeGeometry::BezierCurve ? 4 * segments : points;
    vertex_buffer_.resize(4 * vertices);
    index_buffer_.resize(segments);
    flag_buffer_.resize(s.flags ? segments : 0);
    prepare_curves(batch, l0, l1, part_points_, part_segments_, radius_, geometry_,
                   {vertex_buffer_.data(), index_buffer_.data(), flag_buffer_.data()});
    s.vertices->append(vertex_buffer_.data(), vertices);
    s.indices->append(index_buffer_.data(), segments);
    if (s.flags) s.flags->append(flag_buffer_.data(), segments);
    part_points_ += points;
    part_segments_ += segments;
    if (to != part.end_line) break;
    const float padding[4] = {0, 0, 0, 0};
    s.vertices->append(padding, 1);
    if (!cache_.parallel()) disk_ += close_part(part_);
    ++part_;
    part_points_ = part_segments_ = 0;
    open_ = cache_.parallel();  // in parallel every part is open from the start
  }
  line_ = end;
}

void EmbreeStoreWriter::close(Provenance provenance) {
  if (cache_.parallel()) {
    // Collective: what is left of every rank's rows, then every part in order.
    cache_.write_round();
    for (size_t i = 0; i < parts_.size(); ++i) disk_ += close_part(i);
  } else if (open_ || part_ != parts_.size()) {
    throw OutputError(cache_.path(),
                      "Embree buffers: the lines ended inside part " + std::to_string(part_));
  }
  const nlohmann::json description = {{"geometry", to_string(geometry_)},
                                      {"radius", radius_},
                                      {"attribute", attribute_},
                                      {"parts", parts_.size()}};
  cache_.write_attribute(kEmbreeGroup, "curves", json_text(description));
  provenance.disk_bytes = disk_;
  cache_.write_provenance(kEmbreeGroup, provenance);
}

StoredCurves load_embree(const CacheReader& cache) {
  const std::string where = std::string("group ") + kEmbreeGroup;
  const auto text = cache.attribute(kEmbreeGroup, "curves");
  if (!text)
    throw InputError(cache.path(), where,
                     "missing: no Embree buffers in this cache; add them with: linebake bake " +
                         cache.path() + " --assets embree");
  StoredCurves c;
  size_t parts = 0;
  try {
    const auto j = nlohmann::json::parse(*text);
    c.geometry = parse_embree_geometry(j.at("geometry").get<std::string>());
    c.radius = j.at("radius");
    c.attribute = j.at("attribute");
    parts = j.at("parts");
  } catch (const std::exception& e) {
    throw InputError(cache.path(), where, std::string("bad curve description: ") + e.what());
  }
  // Linear curves and capsules: a vertex per point and neighbour flags.
  const bool point_layout = c.geometry != EmbreeGeometry::BezierCurve;
  for (size_t i = 0; i < parts; ++i) {
    const std::string g = part_group(i);
    PreparedCurves p;
    p.vertices = cache.read<float>(g + "/vertices");
    p.indices = cache.read<uint32_t>(g + "/indices");
    if (point_layout) p.flags = cache.read<uint8_t>(g + "/flags", p.indices.size());
    const uint64_t vertices = p.vertices.size() / 4;
    for (uint64_t s = 0; s < p.indices.size(); ++s)
      // Past the last real vertex (the stored buffer ends with one padding vertex).
      if (uint64_t(p.indices[s]) + (point_layout ? 3 : 5) > vertices)
        throw InputError(cache.path(), "dataset " + g + "/indices",
                         "segment " + std::to_string(s) + " points past the vertices");
    c.parts.push_back(std::move(p));
  }
  return c;
}

}  // namespace linebake
