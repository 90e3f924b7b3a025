#include "diagnostics/cim_pictures.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/png.hpp"

namespace cd {

void write_traversal_png(const std::string& path, BetaVae& vae, const std::vector<float>& base_view,
                         const std::vector<int>& latents) {
  if (latents.empty()) return;
  torch::NoGradGuard no_grad;
  vae->eval();
  const torch::Device device = vae->parameters().front().device();
  torch::Tensor x = torch::from_blob(const_cast<float*>(base_view.data()),
                                     {1, 1, kVaeSize, kVaeSize}, torch::kFloat32).clone().to(device);
  torch::Tensor mu = vae->encode(x).first;  // 1 x L
  const int rows = static_cast<int>(latents.size());
  const int cols = kTraversalColumns;
  // Decodings: per row, the reconstruction and 7 traversal values.
  torch::Tensor z = mu.repeat({rows * 8, 1});
  for (int r = 0; r < rows; ++r)
    for (int k = 0; k < 7; ++k) z[r * 8 + 1 + k][latents[r]] = static_cast<float>(k - 3);
  torch::Tensor images = torch::sigmoid(vae->decode(z)).to(torch::kCPU).contiguous();
  const float* img = images.data_ptr<float>();

  const int S = kTraversalSeparator, C = kTraversalCell;
  const int W = cols * C + (cols + 1) * S, H = rows * C + (rows + 1) * S;
  std::vector<uint8_t> px(static_cast<size_t>(W) * H, 128);  // separators: mid grey
  auto put = [&](int row, int col, const float* src) {
    const int ox = S + col * (C + S), oy = S + row * (C + S);
    for (int y = 0; y < C; ++y)
      for (int xx = 0; xx < C; ++xx) {
        float v = std::clamp(src[(y / 2) * kVaeSize + xx / 2], 0.0f, 1.0f);
        px[static_cast<size_t>(oy + y) * W + ox + xx] = static_cast<uint8_t>(std::lround(v * 255.0f));
      }
  };
  const int plane = kVaeSize * kVaeSize;
  for (int r = 0; r < rows; ++r) {
    put(r, 0, base_view.data());
    for (int k = 0; k < 8; ++k) put(r, 1 + k, img + static_cast<size_t>(r * 8 + k) * plane);
  }
  write_png_gray(path, px, W, H);
}

void write_granger_png(const std::string& path, const std::vector<double>& p_values,
                       const std::vector<bool>& selected, const std::vector<bool>& significant,
                       double threshold_p) {
  const int m = static_cast<int>(p_values.size());
  const int M = kGrangerMargin, BW = kGrangerBarWidth, G = kGrangerGap, PH = kGrangerHeight;
  const int W = 2 * M + m * (BW + G) + G, H = 2 * M + PH;
  std::vector<uint8_t> px(static_cast<size_t>(W) * H * 3, 255);
  auto set = [&](int x, int y, uint8_t r, uint8_t g, uint8_t b) {
    if (x < 0 || y < 0 || x >= W || y >= H) return;
    uint8_t* p = &px[(static_cast<size_t>(y) * W + x) * 3];
    p[0] = r;
    p[1] = g;
    p[2] = b;
  };
  auto score = [](double p) { return p > 0 ? std::min(300.0, -std::log10(p)) : 300.0; };
  const double line = score(threshold_p);
  double top = line;
  for (double p : p_values) top = std::max(top, score(p));
  top = std::max(top * 1.1, 1e-9);
  auto y_of = [&](double v) { return M + PH - static_cast<int>(std::lround(v / top * PH)); };
  // Axes: y at the left, x at the bottom (black).
  for (int y = M; y <= M + PH; ++y) set(M - 1, y, 0, 0, 0);
  for (int x = M - 1; x < W - M; ++x) set(x, M + PH, 0, 0, 0);
  for (int i = 0; i < m; ++i) {
    const int x0 = M + G + i * (BW + G);
    const int y_top = y_of(score(p_values[i]));
    uint8_t r = 150, g = 150, b = 150;
    if (selected[i]) r = 210, g = 30, b = 30;
    else if (significant[i]) r = 240, g = 150, b = 20;
    for (int y = y_top; y < M + PH; ++y)
      for (int x = x0; x < x0 + BW; ++x) set(x, y, r, g, b);
  }
  const int yl = y_of(line);
  for (int x = M - 1; x < W - M; ++x) {
    set(x, yl, 30, 60, 220);
    set(x, yl + 1, 30, 60, 220);
  }
  write_png_rgb(path, px, W, H);
}

}  // namespace cd
