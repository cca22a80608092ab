// Reproduces every number of tests/data/model-vectors.json (a copy of the
// model contract's test vectors, computed by an independent implementation):
// corners to 1e-6 px, 3D points and TCP to 1e-9 mm.
#include <gtest/gtest.h>

#include <cstdio>
#include <vector>

#include "tcpest/common/json.hpp"
#include "tcpest/solver/camera.hpp"
#include "tcpest/solver/instrument.hpp"

namespace tcpest {
namespace solver {
namespace {

std::vector<char> read_file(const char* path) {
  std::vector<char> text;
  std::FILE* f = std::fopen(path, "rb");
  if (f == nullptr) {
    return text;
  }
  char buffer[4096];
  std::size_t n = 0;
  while ((n = std::fread(buffer, 1, sizeof buffer, f)) > 0) {
    text.insert(text.end(), buffer, buffer + n);
  }
  std::fclose(f);
  return text;
}

double num(const json::Document& d, std::size_t obj, const char* key) {
  const auto m = d.member(obj, key);
  EXPECT_TRUE(m.ok()) << key;
  const auto v = d.number(m.value());
  EXPECT_TRUE(v.ok()) << key;
  return v.value();
}

// Verifies: REQ-MODEL-001
TEST(ModelVectors, ReproducesEveryCase) {
  const std::vector<char> text = read_file(TCPEST_TEST_DATA_DIR "/model-vectors.json");
  ASSERT_FALSE(text.empty());
  std::vector<json::Token> tokens(20000);
  json::Document d(tokens.data(), tokens.size());
  ASSERT_TRUE(d.parse(text.data(), text.size()).ok());

  const std::size_t cam = d.member(d.root(), "camera").value();
  CameraIntrinsics k;
  k.width = static_cast<int>(num(d, cam, "width"));
  k.height = static_cast<int>(num(d, cam, "height"));
  k.fx = num(d, cam, "fx");
  k.fy = num(d, cam, "fy");
  k.cx = num(d, cam, "cx");
  k.cy = num(d, cam, "cy");
  k.k1 = num(d, cam, "k1");
  k.k2 = num(d, cam, "k2");
  k.p1 = num(d, cam, "p1");
  k.p2 = num(d, cam, "p2");
  k.k3 = num(d, cam, "k3");
  const auto camera = CameraModel::create(k);
  ASSERT_TRUE(camera.ok());

  const std::size_t ins = d.member(d.root(), "instrument").value();
  const std::size_t nom = d.member(d.root(), "nominal").value();
  InstrumentGeometry g;
  g.bend_length_mm = num(d, ins, "bend_length");
  g.radius_mm = num(d, ins, "radius");
  g.tcp_offset_mm = num(d, ins, "tcp_offset");
  ASSERT_TRUE(d.numbers(d.member(ins, "boundaries").value(), g.boundaries_mm.data(), 6U).ok());
  g.nominal_x_ch_mm = num(d, nom, "x_ch");
  g.nominal_y_ch_mm = num(d, nom, "y_ch");
  g.nominal_psi_rad = num(d, nom, "psi");
  g.nominal_mu_rad = num(d, nom, "mu");
  const auto model = InstrumentModel::create(g);
  ASSERT_TRUE(model.ok());

  const std::size_t cases = d.member(d.root(), "cases").value();
  const std::size_t n = d.array_size(cases);
  ASSERT_GE(n, 16U);
  for (std::size_t i = 0; i < n; ++i) {
    SCOPED_TRACE(testing::Message() << "case " << i);
    const std::size_t c = d.element(cases, i).value();
    PoseVector r;
    ASSERT_TRUE(d.numbers(d.member(c, "r").value(), r.data(), 7U).ok());
    double tcp[3];
    ASSERT_TRUE(d.numbers(d.member(c, "tcp").value(), tcp, 3U).ok());
    CornerSet out;
    model.value().corners(camera.value(), r, out);
    const Vec3 tcp_direct = model.value().tcp(r);
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(out.tcp[a], tcp[a], 1e-9);
      EXPECT_NEAR(tcp_direct[a], tcp[a], 1e-9);
    }
    const std::size_t corners = d.member(c, "corners").value();
    const std::size_t corners3d = d.member(c, "corners_3d").value();
    ASSERT_EQ(d.array_size(corners), 12U);
    for (std::size_t kk = 0; kk < 12U; ++kk) {
      SCOPED_TRACE(testing::Message() << "corner " << kk);
      const std::size_t uv = d.element(corners, kk).value();
      if (d.is_null(uv)) {
        EXPECT_FALSE(out.present[kk]);
        continue;
      }
      ASSERT_TRUE(out.present[kk]);
      double px[2];
      double pt[3];
      ASSERT_TRUE(d.numbers(uv, px, 2U).ok());
      ASSERT_TRUE(d.numbers(d.element(corners3d, kk).value(), pt, 3U).ok());
      EXPECT_NEAR(out.pixel[kk].x(), px[0], 1e-6);
      EXPECT_NEAR(out.pixel[kk].y(), px[1], 1e-6);
      for (int a = 0; a < 3; ++a) {
        EXPECT_NEAR(out.point[kk][a], pt[a], 1e-9);
      }
    }
  }
}

}  // namespace
}  // namespace solver
}  // namespace tcpest
