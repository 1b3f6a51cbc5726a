#include "harness/h5_write.hpp"

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

}  // namespace pbdbench::h5
