// A program built against the installed tcpest (toolchain/check-install.sh):
// solves the pose from 12 corners as `tcpest solve` does (default camera and
// geometry, mid-range start), prints the result in `tcpest solve`'s JSON,
// sends the TCP through the CAN TCP message and decodes it back, and reads a
// loop configuration file. A converged input is assumed (`tcpest solve`
// prints null for the estimate of a refused one).
// Usage: tcpest_consumer CONFIG.yaml U0 V0 ... U11 V11   (nan nan: corner not seen)
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "tcpest/can_iface/messages.hpp"
#include "tcpest/loop/config.hpp"
#include "tcpest/solver/pose_solver.hpp"

namespace {

void print_vector(const char* name, const double* values, int count) {
  std::printf(", \"%s\": [", name);
  for (int i = 0; i < count; ++i) {
    std::printf(i > 0 ? ", %.12g" : "%.12g", values[i]);
  }
  std::printf("]");
}

}  // namespace

int main(int argc, char** argv) {
  using namespace tcpest;
  if (argc != 2 + 2 * solver::kNumCorners) {
    std::fprintf(stderr, "usage: tcpest_consumer CONFIG.yaml U0 V0 ... U11 V11\n");
    return 2;
  }
  solver::CornerObservation observed;
  for (int k = 0; k < solver::kNumCorners; ++k) {
    const double u = std::strtod(argv[2 + 2 * k], nullptr);
    const double v = std::strtod(argv[3 + 2 * k], nullptr);
    observed.pixel[static_cast<std::size_t>(k)] = solver::Vec2(u, v);
    observed.visible[static_cast<std::size_t>(k)] = std::isfinite(u) && std::isfinite(v);
  }
  const auto camera = solver::CameraModel::create(solver::default_pal_camera());
  const auto model = solver::InstrumentModel::create(solver::InstrumentGeometry{});
  if (!camera.ok() || !model.ok()) {
    return 1;
  }
  const solver::InstrumentGeometry& g = model.value().geometry();
  const solver::PoseVector start = g.nominal_pose(0.5 * (g.lambda_min_mm + g.lambda_max_mm), 0.0, 0.0);
  solver::PoseVector r = start;
  solver::PoseSolver pose_solver(camera.value(), model.value());
  const solver::SolveSummary summary = pose_solver.solve(observed, solver::SolveMode::Adaptive, r);
  r = solver::nearest_equivalent_joints(r, start);
  const solver::Vec3 tcp = model.value().tcp(r);
  std::printf("{\"status\": \"%s\"", solver::to_string(summary.status));
  print_vector("tcp", tcp.data(), 3);
  print_vector("r", r.data(), solver::kNumParams);
  std::printf(", \"rms_px\": %.12g, \"iterations\": %d, \"corners_used\": %d}\n", summary.rms_px, summary.iterations,
              summary.corners_used);

  can::TcpMessage sent;
  sent.x_mm = tcp.x();
  sent.y_mm = tcp.y();
  sent.z_mm = tcp.z();
  sent.status = can::EstimateStatus::kValid;
  can::Frame frame;
  if (!can::encode_tcp(can::kDefaultNodeId, sent, frame).ok()) {
    return 1;
  }
  const auto received = can::decode_tcp(can::kDefaultNodeId, frame);
  if (!received.ok()) {
    return 1;
  }
  const double decoded[3] = {received.value().x_mm, received.value().y_mm, received.value().z_mm};
  std::printf("{\"can_id\": %u", static_cast<unsigned>(frame.id));
  print_vector("tcp", decoded, 3);
  std::printf(", \"status\": \"%s\"}\n", can::to_string(received.value().status));

  static yaml::Document scratch;  // large parse buffer
  loop::LoopConfig config;
  const auto loaded = loop::load_loop_config(argv[1], scratch, config);
  if (!loaded.ok()) {
    char message[768];
    loaded.error().format(message, sizeof message);
    std::fprintf(stderr, "config: %s\n", message);
    return 1;
  }
  std::printf("{\"bus\": \"%s\", \"cpu\": %d}\n", config.can.bus, config.rt.cpu);
  return 0;
}
