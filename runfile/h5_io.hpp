// The attribute and dataset conventions the project's HDF5 files share (run, compare, converge
// and regress files): UTF-8 string attributes, float64 and int64 scalars, 1-D and (rows, 3)
// float64 datasets with `units` and `doc` attributes; and the reading of the same. Only runfile/
// includes this header: every other folder reads and writes files through runfile/'s layouts
// (run_file.hpp, compare_file.hpp, converge_file.hpp, regress_file.hpp).
#pragma once

#include <H5Cpp.h>

#include <map>
#include <string>
#include <vector>

#include "core/types.hpp"

namespace pbdbench::h5 {

// ---------------------------------------------------------------------------------------------
// Writing.

H5::StrType utf8();  // variable-length UTF-8 string type
void put(H5::H5Object& obj, const std::string& name, const std::string& value);
void put(H5::H5Object& obj, const std::string& name, double value);
void put(H5::H5Object& obj, const std::string& name, long long value);
// The dataset's `units` (when not empty) and `doc` attributes.
void document(H5::DataSet& ds, const std::string& units, const std::string& doc);
// A 1-D float64 dataset, documented.
void write(H5::Group& g, const std::string& name, const std::vector<double>& v, const std::string& units,
           const std::string& doc);
// A 1-D int64 dataset, documented.
void write(H5::Group& g, const std::string& name, const std::vector<long long>& v,
           const std::string& units, const std::string& doc);
// A (rows, 3) float64 dataset, documented.
void write(H5::Group& g, const std::string& name, const Points& p, const std::string& units,
           const std::string& doc);
// A scalar float64 dataset, documented.
void write_scalar(H5::Group& g, const std::string& name, double value, const std::string& units,
                  const std::string& doc);

// ---------------------------------------------------------------------------------------------
// Reading. Each throws H5::Exception when the object is missing or of another type.

bool exists(const H5::Group& g, const std::string& path);  // every link of `path` exists
std::string get_string(const H5::H5Object& obj, const std::string& name);  // "" when absent
// The scalar string and numeric attributes of an object (integers as doubles).
void read_attributes(const H5::H5Object& obj, std::map<std::string, std::string>& strings,
                     std::map<std::string, double>& numbers);
// A dataset of any rank as doubles (row-major), with its dimensions.
std::vector<double> read_doubles(const H5::DataSet& ds, std::vector<hsize_t>& dims);
std::vector<double> read_doubles(const H5::DataSet& ds);
std::vector<long long> read_integers(const H5::DataSet& ds);
// A (rows, 3) dataset; throws std::runtime_error naming `name` when it has another shape.
Points read_points(const H5::DataSet& ds, const std::string& name);
// A 1-D dataset or attribute of variable-length strings.
std::vector<std::string> read_strings(const H5::DataSet& ds);
std::vector<std::string> read_strings(const H5::Attribute& attr);
// "function: detail" of an HDF5 exception.
std::string message(const H5::Exception& e);

}  // namespace pbdbench::h5
