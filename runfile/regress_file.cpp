#include "runfile/regress_file.hpp"

#include <array>
#include <stdexcept>
#include <variant>

#include "runfile/layout.hpp"
#include "runfile/output_guard.hpp"

namespace pbdbench {

namespace fs = std::filesystem;

namespace {

using Row = RegressFileRow;

// The columns, in the file's order.
struct Column {
  const char* name;
  std::variant<std::string Row::*, double Row::*> field;
};

const std::array<Column, 8> kColumns = {{
    {"case", &Row::case_name},
    {"metric", &Row::metric},
    {"units", &Row::units},
    {"verdict", &Row::verdict},
    {"baseline", &Row::baseline},
    {"now", &Row::now},
    {"change", &Row::change},
    {"allowed", &Row::allowed},
}};

}  // namespace

bool is_regress_file(const fs::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(std::filesystem::symlink_status(path, ec))) return false;
  H5::Exception::dontPrint();
  try {
    const H5::H5File f(path.string(), H5F_ACC_RDONLY);
    for (const Column& c : kColumns)
      if (!f.nameExists(c.name)) return false;
    return true;
  } catch (const H5::Exception&) {
    return false;
  }
}

void write_regress_file(const fs::path& path, const std::vector<RegressFileRow>& rows) {
  layout::write_file(path, "regress", [&](H5::H5File& f) {
    const hsize_t n = rows.size();
    for (const Column& c : kColumns) {
      if (const auto* text = std::get_if<std::string Row::*>(&c.field)) {
        std::vector<const char*> p;
        for (const Row& r : rows) p.push_back((r.*(*text)).c_str());
        H5::StrType type(H5::PredType::C_S1, H5T_VARIABLE);
        H5::DataSet ds = f.createDataSet(c.name, type, H5::DataSpace(1, &n));
        if (n > 0) ds.write(p.data(), type);
      } else {
        const auto number = std::get<double Row::*>(c.field);
        std::vector<double> v;
        for (const Row& r : rows) v.push_back(r.*number);
        H5::DataSet ds = f.createDataSet(c.name, H5::PredType::NATIVE_DOUBLE, H5::DataSpace(1, &n));
        if (n > 0) ds.write(v.data(), H5::PredType::NATIVE_DOUBLE);
      }
    }
  });
}

std::vector<RegressFileRow> read_regress_file(const fs::path& path) {
  std::vector<Row> rows;
  const std::string what = "regress file " + path.string() + ": ";
  layout::read_file(path, "regress", "", [&](const H5::H5File& f) {
    bool first = true;
    for (const Column& c : kColumns) {
      if (!f.nameExists(c.name)) throw std::runtime_error(what + "no column " + c.name);
      const H5::DataSet ds = f.openDataSet(c.name);
      const size_t n = static_cast<size_t>(ds.getSpace().getSimpleExtentNpoints());
      if (first) rows.resize(n);
      first = false;
      if (n != rows.size())
        throw std::runtime_error(what + "column " + c.name + " has " + std::to_string(n) +
                                 " rows, not " + std::to_string(rows.size()));
      if (const auto* text = std::get_if<std::string Row::*>(&c.field)) {
        const std::vector<std::string> v = h5::read_strings(ds);
        for (size_t k = 0; k < n; ++k) rows[k].*(*text) = v[k];
      } else {
        const auto number = std::get<double Row::*>(c.field);
        const std::vector<double> v = h5::read_doubles(ds);
        for (size_t k = 0; k < n; ++k) rows[k].*number = v[k];
      }
    }
  });
  return rows;
}

}  // namespace pbdbench
