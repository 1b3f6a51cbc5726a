#include "runfile/h5_io.hpp"

#include <algorithm>
#include <stdexcept>

namespace pbdbench::h5 {

H5::StrType utf8() {
  H5::StrType type(H5::PredType::C_S1, H5T_VARIABLE);
  type.setCset(H5T_CSET_UTF8);
  return type;
}

void put(H5::H5Object& obj, const std::string& name, const std::string& value) {
  const H5::StrType type = utf8();
  obj.createAttribute(name, type, H5::DataSpace(H5S_SCALAR)).write(type, value);
}

void put(H5::H5Object& obj, const std::string& name, double value) {
  obj.createAttribute(name, H5::PredType::IEEE_F64LE, H5::DataSpace(H5S_SCALAR))
      .write(H5::PredType::NATIVE_DOUBLE, &value);
}

void put(H5::H5Object& obj, const std::string& name, long long value) {
  obj.createAttribute(name, H5::PredType::STD_I64LE, H5::DataSpace(H5S_SCALAR))
      .write(H5::PredType::NATIVE_LLONG, &value);
}

void document(H5::DataSet& ds, const std::string& units, const std::string& doc) {
  if (!units.empty()) put(ds, "units", units);
  put(ds, "doc", doc);
}

void write(H5::Group& g, const std::string& name, const std::vector<double>& v, const std::string& units,
           const std::string& doc) {
  const hsize_t dims[1] = {v.size()};
  H5::DataSet ds = g.createDataSet(name, H5::PredType::IEEE_F64LE, H5::DataSpace(1, dims));
  if (!v.empty()) ds.write(v.data(), H5::PredType::NATIVE_DOUBLE);
  document(ds, units, doc);
}

void write(H5::Group& g, const std::string& name, const std::vector<long long>& v,
           const std::string& units, const std::string& doc) {
  const hsize_t dims[1] = {v.size()};
  H5::DataSet ds = g.createDataSet(name, H5::PredType::STD_I64LE, H5::DataSpace(1, dims));
  if (!v.empty()) ds.write(v.data(), H5::PredType::NATIVE_LLONG);
  document(ds, units, doc);
}

void write(H5::Group& g, const std::string& name, const Points& p, const std::string& units,
           const std::string& doc) {
  const hsize_t dims[2] = {static_cast<hsize_t>(p.rows()), 3};
  H5::DataSet ds = g.createDataSet(name, H5::PredType::IEEE_F64LE, H5::DataSpace(2, dims));
  if (p.rows() > 0) ds.write(p.data(), H5::PredType::NATIVE_DOUBLE);
  document(ds, units, doc);
}

void write_scalar(H5::Group& g, const std::string& name, double value, const std::string& units,
                  const std::string& doc) {
  H5::DataSet ds = g.createDataSet(name, H5::PredType::IEEE_F64LE, H5::DataSpace(H5S_SCALAR));
  ds.write(&value, H5::PredType::NATIVE_DOUBLE);
  document(ds, units, doc);
}

// ---------------------------------------------------------------------------------------------

bool exists(const H5::Group& g, const std::string& path) {
  // nameExists() fails on a path whose intermediate group is missing: check link by link.
  std::string prefix = path.starts_with('/') ? "/" : "";
  size_t start = prefix.size();
  while (start < path.size()) {
    size_t end = path.find('/', start);
    if (end == std::string::npos) end = path.size();
    prefix += path.substr(start, end - start);
    if (!g.nameExists(prefix)) return false;
    prefix += '/';
    start = end + 1;
  }
  return true;
}

std::string get_string(const H5::H5Object& obj, const std::string& name) {
  if (!obj.attrExists(name)) return std::string();
  const H5::Attribute a = obj.openAttribute(name);
  std::string value;
  a.read(a.getStrType(), value);
  return value;
}

void read_attributes(const H5::H5Object& obj, std::map<std::string, std::string>& strings,
                     std::map<std::string, double>& numbers) {
  const int count = obj.getNumAttrs();
  for (int i = 0; i < count; ++i) {
    const H5::Attribute attr = obj.openAttribute(static_cast<unsigned>(i));
    if (attr.getSpace().getSimpleExtentNpoints() != 1) continue;
    switch (attr.getTypeClass()) {
      case H5T_STRING: {
        std::string value;
        attr.read(attr.getStrType(), value);
        strings[attr.getName()] = value;
        break;
      }
      case H5T_INTEGER:
      case H5T_FLOAT: {
        double value = 0.0;
        attr.read(H5::PredType::NATIVE_DOUBLE, &value);
        numbers[attr.getName()] = value;
        break;
      }
      default: break;
    }
  }
}

std::vector<double> read_doubles(const H5::DataSet& ds, std::vector<hsize_t>& dims) {
  const H5::DataSpace space = ds.getSpace();
  dims.assign(static_cast<size_t>(space.getSimpleExtentNdims()), 0);
  if (!dims.empty()) space.getSimpleExtentDims(dims.data());
  hsize_t count = 1;
  for (hsize_t d : dims) count *= d;
  std::vector<double> values(count);
  if (count > 0) ds.read(values.data(), H5::PredType::NATIVE_DOUBLE);
  return values;
}

std::vector<double> read_doubles(const H5::DataSet& ds) {
  std::vector<hsize_t> dims;
  return read_doubles(ds, dims);
}

std::vector<long long> read_integers(const H5::DataSet& ds) {
  std::vector<long long> values(static_cast<size_t>(ds.getSpace().getSimpleExtentNpoints()));
  if (!values.empty()) ds.read(values.data(), H5::PredType::NATIVE_LLONG);
  return values;
}

Points read_points(const H5::DataSet& ds, const std::string& name) {
  std::vector<hsize_t> dims;
  const std::vector<double> v = read_doubles(ds, dims);
  if (dims.size() != 2 || dims[1] != 3) throw std::runtime_error(name + " is not (rows, 3)");
  Points p(static_cast<Eigen::Index>(dims[0]), 3);
  std::copy(v.begin(), v.end(), p.data());
  return p;
}

namespace {

// Variable-length strings read by `read(type, buffer)`, in the object's own character set.
template <class Read>
std::vector<std::string> read_vlen_strings(const H5::DataSpace& space, H5T_cset_t cset, Read read) {
  std::vector<std::string> out;
  const hssize_t n = space.getSimpleExtentNpoints();
  if (n <= 0) return out;
  H5::StrType type(H5::PredType::C_S1, H5T_VARIABLE);
  type.setCset(cset);
  std::vector<char*> buf(static_cast<size_t>(n), nullptr);
  read(type, buf.data());
  for (char* s : buf) out.emplace_back(s ? s : "");
  H5Dvlen_reclaim(type.getId(), space.getId(), H5P_DEFAULT, buf.data());
  return out;
}

}  // namespace

std::vector<std::string> read_strings(const H5::DataSet& ds) {
  return read_vlen_strings(ds.getSpace(), ds.getStrType().getCset(),
                           [&](const H5::StrType& t, char** buf) { ds.read(buf, t); });
}

std::vector<std::string> read_strings(const H5::Attribute& attr) {
  return read_vlen_strings(attr.getSpace(), attr.getStrType().getCset(),
                           [&](const H5::StrType& t, char** buf) { attr.read(t, buf); });
}

std::string message(const H5::Exception& e) {
  std::string msg = e.getFuncName();
  if (!msg.empty()) msg += ": ";
  return msg + e.getDetailMsg();
}

}  // namespace pbdbench::h5
