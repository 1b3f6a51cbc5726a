// Basic numeric types shared by every module.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>  // Vec3::cross is defined here, not in Eigen/Core

namespace pbdbench {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

// A list of points, one row a point: (n x 3), row-major so that frames are contiguous in memory
// and can be written to HDF5 as (n, 3) without a copy.
using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

}  // namespace pbdbench
