#pragma once
// Attention maps of an image policy (seed 001 figure 9): Grad-CAM (Selvaraju et al. 2017) of
// the policy's output over the BEV frame, on recorded frames of a data folder.
//
// For one observation (the frame history of closed loop, through the checkpoint's layout;
// inference/policy_runner.hpp), the network that acts (the policy module; residual's memory
// module in its memory-only layouts) gives its output as one number y (throttle - brake for a
// throttle_brake head, the target speed for a target_speed head) and the last convolutional
// feature map A of its backbone (C x h x w; SmallBackbone: the last conv block, before the
// flatten; ResNet34: the last stage). Then
//   w_k = mean over (i, j) of dy/dA_k(i, j),   map = ReLU(sum_k w_k A_k),
// upsampled bilinearly (torch's align_corners = false) to the frame's H x W and divided by its
// maximum: values in [0, 1]; a map that is zero everywhere stays zero.
//
// Where attention falls: each pixel of the current frame belongs to the channel drawn on top
// there in the BEV's colouring (sense/bev.hpp bev_colour: the highest channel that is on; a
// vehicle on the route is a vehicle) or to "none" (background). A channel's attention share is
// its pixels' part of the map's mass sum(map); its pixel share the part of the frame's pixels
// it covers. Per frame, the attention shares (with "none") sum to 1, or are all 0 for a zero map.
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "inference/policy_runner.hpp"

namespace cd {

struct AttentionOptions {
  std::string checkpoint;        // a `causaldrive train` folder of an image policy
  std::string data;              // a `causaldrive collect` folder
  std::string out;               // where the PNGs and attention.json go (created)
  long frames = 16;              // N >= 1 frames, spread evenly over the selected ones
  std::string select = "stopped";  // stopped | all | light
  double stopped_below = 0.5;    // m/s: `stopped` frames are slower than this
  double light_near = 30.0;      // m: `light` frames have a light (tl_state != 0) nearer
  int scale = 4;                 // each pixel of a panel drawn scale x scale
};

// The selection modes of AttentionOptions::select.
const std::vector<std::string>& attention_selections();

struct AttentionFrame {
  std::string png;      // file name in the output folder
  std::string episode;  // episode file name in the data folder
  int t = 0;
  double speed = 0;
  int command = 0;
  double tl_state = -1, tl_distance = -1;  // -1: the episode has no such series
  double output = 0;                       // the head's output (after the agent's clamping)
  std::vector<float> action;               // the action components
  std::string module;                      // policy | memory
  double map_max = 0;                      // max of ReLU(sum_k w_k A_k) before normalising
  std::vector<double> attention_share;     // per channel, then "none"
  std::vector<double> pixel_share;         // the same, by pixel count
};

struct AttentionReport {
  std::string checkpoint, data, out, method, output, select;
  int history = 0, stride = 0;
  int map_channels = 0, map_height = 0, map_width = 0;  // the feature map Grad-CAM weighs
  // The data's channel names, then "none"; empty for RGB frames (no layers: the shares are
  // empty too).
  std::vector<std::string> channels;
  long candidates = 0;                // frames matching `select` (with a full history)
  std::vector<AttentionFrame> frames;
  long attended_frames = 0;           // frames whose map is not all zero
  // Means over the attended frames (zeros when there is none).
  std::vector<double> mean_attention_share, mean_pixel_share;
};

// Grad-CAM of one feature map and its gradient, upsampled to height x width (row major),
// normalised to [0, 1]. `raw_max` (when given) receives the maximum before normalising.
std::vector<float> grad_cam(const FeatureMapGradient& g, int height, int width,
                            double* raw_max = nullptr);

// Bilinear resampling of an h x w map to H x W as torch's interpolate (align_corners = false).
std::vector<float> resize_bilinear(const std::vector<float>& map, int h, int w, int height,
                                   int width);

// Per pixel of a C x H x W frame (non-zero = on): the highest channel on there, or C for none.
std::vector<int> top_channel(const unsigned char* frame, int channels, int height, int width);

// The grid of one frame as RGB (width 3 * W * scale + 2 * kAttentionSeparator, height
// H * scale): the frame in the BEV's colours (`rgb`: its own, the camera's) | the map as a heat
// image | the map over the frame.
inline constexpr int kAttentionSeparator = 2;
std::vector<unsigned char> attention_grid(const unsigned char* frame, int channels, int height,
                                          int width, const std::vector<float>& map, int scale,
                                          int* grid_width, int* grid_height, bool rgb = false);

// Runs the command: N PNGs and attention.json (atomic) in options.out. Throws ConfigError for
// N < 1, an unknown selection or a run folder that is not an image policy (dim, cim: the
// message lists the supported methods), DataError for a missing or damaged checkpoint or
// data, data whose frame format differs, no frame to select.
AttentionReport run_attention(const AttentionOptions& options);

nlohmann::json attention_report_json(const AttentionReport& report);
std::string attention_report_table(const AttentionReport& report);

}  // namespace cd
