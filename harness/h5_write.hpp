// The attribute and dataset conventions the harness's HDF5 files share (compare and
// convergence files, like the run files): UTF-8 string attributes, float64 and int64 scalars,
// 1-D float64 datasets with `units` and `doc` attributes.
#pragma once

#include <H5Cpp.h>

#include <string>
#include <vector>

namespace pbdbench::h5 {

H5::StrType utf8();  // variable-length UTF-8 string type
void put(H5::H5Object& obj, const std::string& name, const std::string& value);
void put(H5::H5Object& obj, const std::string& name, double value);
void put(H5::H5Object& obj, const std::string& name, long long value);
// The dataset's `units` (when not empty) and `doc` attributes.
void document(H5::DataSet& ds, const std::string& units, const std::string& doc);
// A 1-D float64 dataset, documented.
void write(H5::Group& g, const std::string& name, const std::vector<double>& v, const std::string& units,
           const std::string& doc);

}  // namespace pbdbench::h5
