// Micro-benchmarks of the per-step work outside SUMO: BEV rendering and box overlap.
// Run: build/causaldrive_benchmarks (Google Benchmark flags apply).
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "sense/bev.hpp"
#include "world/collision.hpp"

namespace {

// A 10 x 10 grid of two-way streets, 100 m blocks: about the size of the built-in towns.
const cd::RoadMap& grid_map() {
  static const cd::RoadMap map = [] {
    cd::RoadMap m;
    for (int i = 0; i <= 10; ++i)
      for (int dir = 0; dir < 2; ++dir)
        for (int axis = 0; axis < 2; ++axis) {
          cd::LaneGeom g;
          g.id = "l" + std::to_string(i) + "_" + std::to_string(dir) + "_" + std::to_string(axis);
          g.edge = g.id;
          g.width = 3.5;
          double off = dir ? 1.75 : -1.75, c = i * 100.0;
          cd::Vec2 a = axis ? cd::Vec2{c + off, 0} : cd::Vec2{0, c + off};
          cd::Vec2 b = axis ? cd::Vec2{c + off, 1000} : cd::Vec2{1000, c + off};
          g.shape = dir ? cd::Polyline{b, a} : cd::Polyline{a, b};
          g.length = 1000;
          m.add(g);
        }
    return m;
  }();
  return map;
}

cd::BevScene busy_scene(int frame) {
  cd::BevScene s;
  s.ego = {{498.0 + 0.3 * frame, 501.75}, 0.05 * std::sin(frame * 0.1)};
  for (int k = 0; k < 10; ++k)
    s.vehicles.push_back({{500.0 + 6 * k, 501.75 + (k % 2 ? 3.5 : 0)}, 0.0, 4.5, 1.8});
  for (int k = 0; k < 4; ++k) s.pedestrians.push_back({{505.0 + k, 506.0}, 1.57, 0.5, 0.5});
  s.stop_lines.push_back({{520, 500}, {520, 503.5}, cd::kBevLightRed});
  return s;
}

void BM_RenderPacked(benchmark::State& state) {
  cd::BevRenderer r(grid_map(), cd::BevConfig{});
  std::vector<uint8_t> out(size_t(r.config().height) * r.config().width);
  int frame = 0;
  for (auto _ : state) {
    r.render_packed(busy_scene(frame++ % 100), out.data());
    benchmark::DoNotOptimize(out.data());
  }
}
BENCHMARK(BM_RenderPacked);

void BM_RenderPlanes(benchmark::State& state) {
  cd::BevRenderer r(grid_map(), cd::BevConfig{});
  std::vector<uint8_t> out(r.frame_bytes());
  int frame = 0;
  for (auto _ : state) {
    r.render(busy_scene(frame++ % 100), out.data());
    benchmark::DoNotOptimize(out.data());
  }
}
BENCHMARK(BM_RenderPlanes);

void BM_BoxesOverlap(benchmark::State& state) {
  cd::Box a{{0, 0}, 0.3, 4.5, 1.8}, b{{3.0, 1.0}, 1.2, 4.5, 1.8};
  for (auto _ : state) {
    benchmark::DoNotOptimize(cd::boxes_overlap(a, b));
    b.center.x += 1e-9;
  }
}
BENCHMARK(BM_BoxesOverlap);

}  // namespace
