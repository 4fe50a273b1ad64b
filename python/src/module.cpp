// The `linebake` Python module: line sets from and to NumPy, every format, bakes, caches,
// renders and image metrics, through the same library calls as the CLI (issue 24).

#include "bindings.hpp"
#include "core/h5.hpp"

namespace linebake::python {

py::object to_python(const nlohmann::json& value) {
  using Type = nlohmann::json::value_t;
  switch (value.type()) {
    case Type::boolean:
      return py::bool_(value.get<bool>());
    case Type::number_integer:
      return py::int_(value.get<int64_t>());
    case Type::number_unsigned:
      return py::int_(value.get<uint64_t>());
    case Type::number_float:
      return py::float_(value.get<double>());
    case Type::string:
      return py::str(value.get_ref<const std::string&>());
    case Type::array: {
      py::list list;
      for (const nlohmann::json& element : value) list.append(to_python(element));
      return list;
    }
    case Type::object: {
      py::dict dict;
      for (const auto& [key, element] : value.items()) dict[py::str(key)] = to_python(element);
      return dict;
    }
    default:  // null, binary, discarded
      return py::none();
  }
}

py::object keep_alive(std::shared_ptr<const void> owner) {
  auto* held = new std::shared_ptr<const void>(std::move(owner));
  return py::capsule(
      held, [](void* pointer) { delete static_cast<std::shared_ptr<const void>*>(pointer); });
}

std::string option_name(const std::string& keyword) {
  std::string name = keyword;
  for (char& c : name)
    if (c == '_') c = '-';
  return name;
}

std::vector<std::string> option_names(const py::kwargs& options) {
  std::vector<std::string> names;
  for (const auto& item : options) names.push_back(option_name(py::str(item.first)));
  return names;
}

}  // namespace linebake::python

PYBIND11_MODULE(linebake, module) {
  using namespace linebake::python;
  // Before anything touches HDF5: no error stacks printed, Debian's filter plugins registered.
  linebake::h5::init();
  module.doc() =
      "linebake: 3D line sets (streamlines, trajectories) to tube meshes, voxel grids and asset "
      "caches; renders with transparency techniques; PSNR and SSIM.";
  module.attr("__version__") = LINEBAKE_VERSION;
  // pybind11 looks NumPy's C API up on first use, under a static guard that waits holding the
  // GIL: threads making their first arrays at once deadlocked. Looked up here, once.
  (void)py::array_t<float>(0);
  bind_errors(module);
  bind_line_sets(module);
  bind_assets(module);
  bind_rendering(module);
}
