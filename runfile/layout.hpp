// A file layout declared once, as tables: each attribute and each dataset of a file kind has a
// name, units, a doc string and one accessor into the struct the file stores, and the writer and
// the reader both walk the same tables (as the run file's series follow runfile/series.cpp).
// The tables are run_file.cpp's (the root attributes), compare_file.cpp's and converge_file.cpp's
// (regress_file.cpp's columns are plainer), and the provenance every file carries (layout.cpp);
// each kind publishes its attribute tables as AttributeInfo rows (runfile/file_read.hpp) for the
// tests and results/README.md. write_file and read_file open every kind. Only runfile/ includes
// this header.
//
//   PBDBENCH_ATTRIBUTE(T, "name", "units", "doc", member)    an attribute stored in T::member
//   PBDBENCH_DERIVED(T, "name", "units", "doc", expression)  written from an expression of `r` (a
//                                                   const T&), not read back (constants, summaries)
//   PBDBENCH_DATASET(T, "path", "units", "doc", member [, present [, doc_of]])
//                                                   a dataset of T::member, written when
//                                                   present(r) (null: always), its doc doc_of(r)
//                                                   where that depends on r
#pragma once

#include <array>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <type_traits>
#include <variant>
#include <vector>

#include "runfile/file_read.hpp"
#include "runfile/h5_io.hpp"

namespace pbdbench::layout {

// ---------------------------------------------------------------------------------------------
// Attributes: UTF-8 strings, float64 or int64 scalars.

using Value = std::variant<std::string, double, long long>;

inline Value value_of(const std::string& v) { return v; }
inline Value value_of(double v) { return v; }
template <class I>
  requires std::is_integral_v<I>
Value value_of(I v) {
  return static_cast<long long>(v);
}

inline void assign(std::string& out, const Value& v) {
  if (const auto* s = std::get_if<std::string>(&v)) out = *s;
}
inline void assign(double& out, const Value& v) {
  if (const auto* d = std::get_if<double>(&v)) out = *d;
  if (const auto* i = std::get_if<long long>(&v)) out = static_cast<double>(*i);
}
template <class I>
  requires std::is_integral_v<I>
void assign(I& out, const Value& v) {
  if (const auto* i = std::get_if<long long>(&v)) out = static_cast<I>(*i);
  if (const auto* d = std::get_if<double>(&v)) out = static_cast<I>(*d);
}

template <class T>
struct AttributeSpec {
  std::string_view name;
  std::string_view units;  // "" for none
  std::string_view doc;
  Value (*get)(const T& r);
  void (*set)(T& r, const Value& v) = nullptr;  // null: derived when written, not read back
};

#define PBDBENCH_ATTRIBUTE(T, name, units, doc, member)                              \
  ::pbdbench::layout::AttributeSpec<T> {                                             \
    name, units, doc, [](const T& r) { return ::pbdbench::layout::value_of(r.member); },    \
        [](T& r, const ::pbdbench::layout::Value& v) {                               \
          ::pbdbench::layout::assign(r.member, v);                                   \
        }                                                                            \
  }
#define PBDBENCH_DERIVED(T, name, units, doc, expression)                                          \
  ::pbdbench::layout::AttributeSpec<T> {                                                           \
    name, units, doc, []([[maybe_unused]] const T& r) { return ::pbdbench::layout::value_of(expression); }, \
        nullptr                                                                                    \
  }

inline void put(H5::H5Object& obj, const std::string& name, const Value& v) {
  std::visit([&](const auto& x) { h5::put(obj, name, x); }, v);
}

inline Value get(const H5::Attribute& a) {
  switch (a.getTypeClass()) {
    case H5T_STRING: {
      std::string s;
      a.read(a.getStrType(), s);
      return s;
    }
    case H5T_INTEGER: {
      long long i = 0;
      a.read(H5::PredType::NATIVE_LLONG, &i);
      return i;
    }
    default: {
      double d = 0.0;
      a.read(H5::PredType::NATIVE_DOUBLE, &d);
      return d;
    }
  }
}

template <class T, size_t N>
void write_attributes(H5::H5Object& obj, const std::array<AttributeSpec<T>, N>& table, const T& r) {
  for (const AttributeSpec<T>& a : table) put(obj, std::string(a.name), a.get(r));
}

// Sets every stored (not derived) attribute of the table that the object has.
template <class T, size_t N>
void read_attributes(const H5::H5Object& obj, const std::array<AttributeSpec<T>, N>& table, T& r) {
  for (const AttributeSpec<T>& a : table) {
    const std::string name(a.name);
    if (a.set != nullptr && obj.attrExists(name)) a.set(r, get(obj.openAttribute(name)));
  }
}

// The table's rows as AttributeInfo (the type is the one its accessor gives on a default T).
inline AttributeType type_of(const Value& v) {
  if (std::holds_alternative<std::string>(v)) return AttributeType::Text;
  return std::holds_alternative<long long>(v) ? AttributeType::Integer : AttributeType::Real;
}
template <class T, size_t N>
void describe(const std::array<AttributeSpec<T>, N>& table, std::vector<AttributeInfo>& out) {
  const T blank{};
  for (const AttributeSpec<T>& a : table)
    out.push_back({std::string(a.name), type_of(a.get(blank)), std::string(a.units), std::string(a.doc),
                   a.set != nullptr});
}

// ---------------------------------------------------------------------------------------------
// Datasets: 1-D float64 or int64, (rows, 3) float64, (rows, 2) int64, or a float64 scalar.

using IndexPairs = std::vector<std::array<long long, 2>>;
using Array = std::variant<std::vector<double>, std::vector<long long>, Points, IndexPairs, double>;

inline Array array_of(const std::vector<double>& v) { return v; }
inline Array array_of(const std::vector<long>& v) { return std::vector<long long>(v.begin(), v.end()); }
inline Array array_of(const Points& v) { return v; }
inline Array array_of(const IndexPairs& v) { return v; }
inline Array array_of(double v) { return v; }
inline Array array_of(int v) { return static_cast<double>(v); }  // a count as a float64 scalar

inline void assign(std::vector<double>& out, Array&& a) {
  if (auto* v = std::get_if<std::vector<double>>(&a)) out = std::move(*v);
}
inline void assign(std::vector<long>& out, Array&& a) {
  if (auto* v = std::get_if<std::vector<long long>>(&a)) out.assign(v->begin(), v->end());
}
inline void assign(Points& out, Array&& a) {
  if (auto* v = std::get_if<Points>(&a)) out = std::move(*v);
}
inline void assign(IndexPairs& out, Array&& a) {
  if (auto* v = std::get_if<IndexPairs>(&a)) out = std::move(*v);
}
inline void assign(double& out, Array&& a) {
  if (auto* v = std::get_if<double>(&a)) out = *v;
}
inline void assign(int& out, Array&& a) {
  if (auto* v = std::get_if<double>(&a)) out = static_cast<int>(*v);
}

template <class T>
struct DatasetSpec {
  std::string_view path;   // relative to the layout's group ("time", "observables/x_run")
  std::string_view units;  // "" for none (no `units` attribute)
  std::string_view doc;
  Array (*get)(const T& r);
  void (*set)(T& r, Array&& a);
  bool (*present)(const T& r) = nullptr;  // written only when true (null: always)
  std::string (*doc_of)(const T& r) = nullptr;  // a doc that depends on r (null: `doc`)
};

#define PBDBENCH_DATASET(T, path, units, doc, member, ...)                               \
  ::pbdbench::layout::DatasetSpec<T> {                                                   \
    path, units, doc, [](const T& r) { return ::pbdbench::layout::array_of(r.member); }, \
        [](T& r, ::pbdbench::layout::Array&& a) {                                        \
          ::pbdbench::layout::assign(r.member, std::move(a));                            \
        },                                                                               \
        __VA_ARGS__                                                                      \
  }

void write_array(H5::Group& g, const std::string& name, const Array& a, const std::string& units,
                 const std::string& doc);
// The dataset as the Array alternative its type and shape give.
Array read_array(const H5::DataSet& ds);

// `g`'s subgroup `path` (created when missing).
H5::Group subgroup(H5::Group& g, const std::string& path);

template <class T, size_t N>
void write_datasets(H5::Group& g, const std::array<DatasetSpec<T>, N>& table, const T& r) {
  for (const DatasetSpec<T>& d : table) {
    if (d.present != nullptr && !d.present(r)) continue;
    const std::string path(d.path);
    const size_t slash = path.rfind('/');
    H5::Group parent = slash == std::string::npos ? g : subgroup(g, path.substr(0, slash));
    write_array(parent, slash == std::string::npos ? path : path.substr(slash + 1), d.get(r),
                std::string(d.units), d.doc_of != nullptr ? d.doc_of(r) : std::string(d.doc));
  }
}

// Sets every dataset of the table that the group has.
template <class T, size_t N>
void read_datasets(const H5::Group& g, const std::array<DatasetSpec<T>, N>& table, T& r) {
  for (const DatasetSpec<T>& d : table) {
    const std::string path(d.path);
    if (h5::exists(g, path)) d.set(r, read_array(g.openDataSet(path)));
  }
}

}  // namespace pbdbench::layout

namespace pbdbench::layout {

// This build's provenance, created now (utc_now(), runfile/build_info.hpp).
Provenance current_provenance();
// The attributes of provenance_attributes() (created, pbdbench_version, git_commit, compiler,
// build_type, cxx_flags), in this order: `p`'s, or this build's now.
void write_provenance(H5::H5Object& obj, const Provenance& p);
void write_provenance(H5::H5Object& obj);
Provenance read_provenance(const H5::H5Object& obj);

// Lines joined with '\n' (a `warnings` attribute), and split back (empty lines dropped).
std::string join_lines(const std::vector<std::string>& lines);
std::vector<std::string> split_lines(const std::string& text);

// Creates the file `path` (and its folder, replacing a file there) and calls write(file); every
// failure is a std::runtime_error "<kind> file <path>: ...".
void write_file(const std::filesystem::path& path, const std::string& kind,
                const std::function<void(H5::H5File&)>& write);

// Opens the existing file `path` of the kind whose root attribute `content` is `content`
// ("pbdbench compare"; "" for a kind without one) and calls read(file); every failure (missing,
// not HDF5, of another kind, unreadable) is a std::runtime_error "<kind> file <path>: ...".
void read_file(const std::filesystem::path& path, const std::string& kind, const std::string& content,
               const std::function<void(const H5::H5File&)>& read);

}  // namespace pbdbench::layout
