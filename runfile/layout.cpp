#include "runfile/layout.hpp"

namespace pbdbench::layout {

void write_array(H5::Group& g, const std::string& name, const Array& a, const std::string& units,
                 const std::string& doc) {
  if (const auto* pairs = std::get_if<IndexPairs>(&a)) {
    const hsize_t dims[2] = {pairs->size(), 2};
    H5::DataSet ds = g.createDataSet(name, H5::PredType::STD_I64LE, H5::DataSpace(2, dims));
    if (!pairs->empty()) ds.write(pairs->data(), H5::PredType::NATIVE_LLONG);
    h5::document(ds, units, doc);
  } else if (const auto* scalar = std::get_if<double>(&a)) {
    h5::write_scalar(g, name, *scalar, units, doc);
  } else {
    std::visit(
        [&](const auto& v) {
          if constexpr (!std::is_same_v<std::decay_t<decltype(v)>, IndexPairs> &&
                        !std::is_same_v<std::decay_t<decltype(v)>, double>)
            h5::write(g, name, v, units, doc);
        },
        a);
  }
}

Array read_array(const H5::DataSet& ds) {
  const H5::DataSpace space = ds.getSpace();
  const int rank = space.getSimpleExtentNdims();
  std::vector<hsize_t> dims(static_cast<size_t>(rank), 0);
  if (rank > 0) space.getSimpleExtentDims(dims.data());
  const bool integer = ds.getTypeClass() == H5T_INTEGER;
  if (rank == 0) return h5::read_doubles(ds).at(0);
  if (rank == 1) {
    if (integer) return h5::read_integers(ds);
    return h5::read_doubles(ds);
  }
  if (rank == 2 && dims[1] == 2 && integer) {
    const std::vector<long long> flat = h5::read_integers(ds);
    IndexPairs pairs(dims[0]);
    for (size_t k = 0; k < pairs.size(); ++k) pairs[k] = {flat[2 * k], flat[2 * k + 1]};
    return pairs;
  }
  return h5::read_points(ds, ds.getObjName());
}

H5::Group subgroup(H5::Group& g, const std::string& path) {
  return g.nameExists(path) ? g.openGroup(path) : g.createGroup(path);
}

}  // namespace pbdbench::layout

#include <stdexcept>

#include "runfile/build_info.hpp"
#include "runfile/output_guard.hpp"
#include "runfile/utc_now.hpp"

namespace pbdbench::layout {

namespace {

const std::array kProvenance = {
    PBDBENCH_ATTRIBUTE(Provenance, "created", "", "when the file was created, ISO 8601 UTC (`2025-01-31T12:00:00Z`)",
                       created),
    PBDBENCH_ATTRIBUTE(Provenance, "pbdbench_version", "", "the project version of the build that wrote the file",
                       pbdbench_version),
    PBDBENCH_ATTRIBUTE(Provenance, "git_commit", "",
                       "the commit of that build, with `+dirty` when tracked files were modified", git_commit),
    PBDBENCH_ATTRIBUTE(Provenance, "compiler", "", "compiler and version, e.g. `GNU 12.2.0`", compiler),
    PBDBENCH_ATTRIBUTE(Provenance, "build_type", "", "CMake build type, e.g. `Release`", build_type),
    PBDBENCH_ATTRIBUTE(Provenance, "cxx_flags", "", "the flags the sources were compiled with", cxx_flags),
};

}  // namespace

Provenance current_provenance() {
  const BuildInfo& b = build_info();
  return {utc_now(), b.version, b.git_commit, b.compiler, b.build_type, b.cxx_flags};
}

void write_provenance(H5::H5Object& obj, const Provenance& p) { write_attributes(obj, kProvenance, p); }
void write_provenance(H5::H5Object& obj) { write_provenance(obj, current_provenance()); }

Provenance read_provenance(const H5::H5Object& obj) {
  Provenance p;
  read_attributes(obj, kProvenance, p);
  return p;
}

std::string join_lines(const std::vector<std::string>& lines) {
  std::string text;
  for (const std::string& l : lines) text += (text.empty() ? "" : "\n") + l;
  return text;
}

std::vector<std::string> split_lines(const std::string& text) {
  std::vector<std::string> out;
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    if (end > start) out.push_back(text.substr(start, end - start));
    start = end + 1;
  }
  return out;
}

void write_file(const std::filesystem::path& path, const std::string& kind,
                const std::function<void(H5::H5File&)>& write) {
  const std::string what = kind + " file " + path.string() + ": ";
  H5::Exception::dontPrint();
  // Written whole beside the path, then renamed onto it: an interrupted write leaves the earlier
  // file as it was, and nothing planted at the path or at its temporary is written through.
  std::filesystem::path tmp;  // set once this process created it
  try {
    if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
    const std::filesystem::path claimed = claim_temporary(path);
    {
      H5::H5File file(claimed.string(), H5F_ACC_EXCL);
      tmp = claimed;
      write(file);
    }
    std::filesystem::rename(claimed, path);
  } catch (const H5::Exception& e) {
    std::error_code ec;
    if (!tmp.empty()) std::filesystem::remove(tmp, ec);
    throw std::runtime_error(what + "cannot write: " + h5::message(e));
  } catch (const std::filesystem::filesystem_error& e) {
    std::error_code ec;
    if (!tmp.empty()) std::filesystem::remove(tmp, ec);
    throw std::runtime_error(what + e.what());
  } catch (...) {
    std::error_code ec;
    if (!tmp.empty()) std::filesystem::remove(tmp, ec);
    throw;
  }
}

void read_file(const std::filesystem::path& path, const std::string& kind, const std::string& content,
               const std::function<void(const H5::H5File&)>& read) {
  const std::string what = kind + " file " + path.string() + ": ";
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw std::runtime_error(what + "no such file");
  H5::Exception::dontPrint();
  try {
    const H5::H5File file(path.string(), H5F_ACC_RDONLY);
    const std::string found = h5::get_string(file, "content");
    if (!content.empty() && found != content)
      throw std::runtime_error(what + "not a " + kind + " file (content \"" + found + "\", not \"" +
                               content + "\")");
    read(file);
  } catch (const H5::Exception& e) {
    throw std::runtime_error(what + "cannot read: " + h5::message(e));
  }
}

}  // namespace pbdbench::layout

namespace pbdbench {

const char* to_string(AttributeType type) {
  switch (type) {
    case AttributeType::Text: return "str";
    case AttributeType::Integer: return "int";
    case AttributeType::Real: return "float";
  }
  return "unknown";
}

std::string attributes_markdown(const std::vector<AttributeInfo>& attributes) {
  auto cell = [](const std::string& text) {
    std::string out;
    for (char c : text) out += c == '|' ? std::string("\\|") : std::string(1, c);
    return out;
  };
  std::string md = "| attribute | type | units | meaning |\n|---|---|---|---|\n";
  for (const AttributeInfo& a : attributes)
    md += "| `" + a.name + "` | " + to_string(a.type) + " | " + cell(a.units) + " | " + cell(a.doc) + " |\n";
  return md;
}

std::vector<AttributeInfo> provenance_attributes() {
  std::vector<AttributeInfo> out;
  layout::describe(layout::kProvenance, out);
  return out;
}

}  // namespace pbdbench
