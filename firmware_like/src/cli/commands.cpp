#include "cli/commands.hpp"

namespace tcpest {
namespace cli {

const Command* commands(int& count) noexcept {
  static const Command kCommands[] = {
      {"demo", "run the full loop on the built-in synthetic scene and report accuracy and timing", cmd_demo},
      {"run", "the estimation loop as deployed: frames in, TCP estimates out on CAN", cmd_run},
      {"listen", "the controllers' side: decode and check the estimator's CAN frames (interface or candump log)",
       cmd_listen},
      {"estimate", "extract corners and solve the pose on image files", cmd_estimate},
      {"evaluate", "run the pipeline over an annotated dataset and score it against its ground truth",
       cmd_evaluate},
      {"solve", "solve the pose from given corners (bring your own detector)", cmd_solve},
      {"project", "project the model: corners and TCP for a configuration r", cmd_project},
      {"render", "render synthetic endoscopic images with exact ground truth", cmd_render},
      {"train-colors", "train the blue/yellow colour model from marked frames", cmd_train_colors},
      {"study", "simulated studies (play: the paper's laboratory experiment)", cmd_study},
      {"bench", "time the loop and its steps on a fixed dataset", cmd_bench},
  };
  count = static_cast<int>(sizeof kCommands / sizeof kCommands[0]);
  return kCommands;
}

}  // namespace cli
}  // namespace tcpest
