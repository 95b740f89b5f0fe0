// Reads a PCD file with PCL's typed loader, pcl::io::loadPCDFile<PointT>, into the
// point struct a ROS LiDAR driver registers with POINT_CLOUD_REGISTER_POINT_STRUCT,
// and prints every point, one row per point, fields in the struct's order.
//
//   pcl_typed_reader TYPE FILE.pcd     TYPE: rls velodyne ouster hesai autoware
//
// Field names and types follow each driver's definition (see docs/formats.md for the
// repository and path of each); the structs are declared here so that the test needs
// only PCL, not the drivers. PCL maps a file's field onto a struct member only when
// the name, the type and the count match; a mismatch leaves the member at its default
// and prints "Failed to find match for field", which the test treats as a failure.

#define PCL_NO_PRECOMPILE
#include <pcl/io/pcd_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <cinttypes>
#include <cstdio>
#include <cstring>

namespace rls_test {

struct EIGEN_ALIGN16 RlsPoint {  // rls_addon/core/io/fields.py FILE_TYPES
  PCL_ADD_POINT4D;
  float intensity;
  std::uint16_t ring;
  double time;
  std::uint32_t label;
  std::uint32_t instance;
  std::uint8_t ghost;
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

struct EIGEN_ALIGN16 VelodynePoint {  // velodyne_pcl::PointXYZIRT
  PCL_ADD_POINT4D;
  float intensity;
  std::uint16_t ring;
  float time;
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

struct EIGEN_ALIGN16 OusterPoint {  // ouster_ros::Point
  PCL_ADD_POINT4D;
  float intensity;
  std::uint32_t t;
  std::uint16_t reflectivity;
  std::uint16_t ring;
  std::uint16_t ambient;
  std::uint32_t range;
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

struct EIGEN_ALIGN16 HesaiPoint {  // HesaiLidar_ROS_2.0's PointCloud2 fields
  PCL_ADD_POINT4D;
  float intensity;
  std::uint16_t ring;
  double timestamp;
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

struct AutowarePoint {  // autoware::point_types::PointXYZIRC (no PCL_ADD_POINT4D)
  float x;
  float y;
  float z;
  std::uint8_t intensity;
  std::uint8_t return_type;
  std::uint16_t channel;
};

}  // namespace rls_test

POINT_CLOUD_REGISTER_POINT_STRUCT(rls_test::RlsPoint,
    (float, x, x)(float, y, y)(float, z, z)(float, intensity, intensity)
    (std::uint16_t, ring, ring)(double, time, time)(std::uint32_t, label, label)
    (std::uint32_t, instance, instance)(std::uint8_t, ghost, ghost))

POINT_CLOUD_REGISTER_POINT_STRUCT(rls_test::VelodynePoint,
    (float, x, x)(float, y, y)(float, z, z)(float, intensity, intensity)
    (std::uint16_t, ring, ring)(float, time, time))

POINT_CLOUD_REGISTER_POINT_STRUCT(rls_test::OusterPoint,
    (float, x, x)(float, y, y)(float, z, z)(float, intensity, intensity)
    (std::uint32_t, t, t)(std::uint16_t, reflectivity, reflectivity)
    (std::uint16_t, ring, ring)(std::uint16_t, ambient, ambient)
    (std::uint32_t, range, range))

POINT_CLOUD_REGISTER_POINT_STRUCT(rls_test::HesaiPoint,
    (float, x, x)(float, y, y)(float, z, z)(float, intensity, intensity)
    (std::uint16_t, ring, ring)(double, timestamp, timestamp))

POINT_CLOUD_REGISTER_POINT_STRUCT(rls_test::AutowarePoint,
    (float, x, x)(float, y, y)(float, z, z)(std::uint8_t, intensity, intensity)
    (std::uint8_t, return_type, return_type)(std::uint16_t, channel, channel))

namespace {

// 17 significant digits: a float (widened to double) and a double read back exactly.
void put(float v) { std::printf(" %.17g", static_cast<double>(v)); }
void put(double v) { std::printf(" %.17g", v); }
void put(std::uint8_t v) { std::printf(" %u", static_cast<unsigned>(v)); }
void put(std::uint16_t v) { std::printf(" %u", static_cast<unsigned>(v)); }
void put(std::uint32_t v) { std::printf(" %" PRIu32, v); }

template <typename PointT>
pcl::PointCloud<PointT> load(const char* path, bool* ok) {
  pcl::PointCloud<PointT> cloud;
  *ok = pcl::io::loadPCDFile<PointT>(path, cloud) == 0;
  if (*ok) std::printf("points %zu\n", cloud.size());
  return cloud;
}

// One output row: "p" and the point's fields.
#define ROW(...) do { std::printf("p"); __VA_ARGS__; std::printf("\n"); } while (0)

int run(const char* type, const char* path) {
  bool ok = false;
  if (!std::strcmp(type, "rls")) {
    auto c = load<rls_test::RlsPoint>(path, &ok);
    for (const auto& p : c) ROW(put(p.x); put(p.y); put(p.z); put(p.intensity); put(p.ring);
                                put(p.time); put(p.label); put(p.instance); put(p.ghost));
  } else if (!std::strcmp(type, "velodyne")) {
    auto c = load<rls_test::VelodynePoint>(path, &ok);
    for (const auto& p : c) ROW(put(p.x); put(p.y); put(p.z); put(p.intensity); put(p.ring);
                                put(p.time));
  } else if (!std::strcmp(type, "ouster")) {
    auto c = load<rls_test::OusterPoint>(path, &ok);
    for (const auto& p : c) ROW(put(p.x); put(p.y); put(p.z); put(p.intensity); put(p.t);
                                put(p.reflectivity); put(p.ring); put(p.ambient); put(p.range));
  } else if (!std::strcmp(type, "hesai")) {
    auto c = load<rls_test::HesaiPoint>(path, &ok);
    for (const auto& p : c) ROW(put(p.x); put(p.y); put(p.z); put(p.intensity); put(p.ring);
                                put(p.timestamp));
  } else if (!std::strcmp(type, "autoware")) {
    auto c = load<rls_test::AutowarePoint>(path, &ok);
    for (const auto& p : c) ROW(put(p.x); put(p.y); put(p.z); put(p.intensity);
                                put(p.return_type); put(p.channel));
  } else {
    std::fprintf(stderr, "unknown point type %s\n", type);
    return 2;
  }
  return ok ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s TYPE FILE.pcd\n", argv[0]);
    return 2;
  }
  return run(argv[1], argv[2]);
}
