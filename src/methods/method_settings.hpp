#pragma once
// The training settings of seed 001's methods ([keyframe], [hd], [dagger]); torch-free. The
// network-shaping ones ([residual], [fca]) are in nn/model_settings.hpp.
// Paper values are the defaults where the paper or the cited methods' public code gives one
// (../shared/DESIGN.md "Copycat baselines"); every other choice is said here.
#include <cstdint>
#include <string>

namespace cd {

// keyframe: samples where the action changes are up-weighted by their action-prediction error.
struct KeyframeSettings {
  std::string mode = "threshold";  // threshold | softmax
  int actions = 9;                 // previous actions the action-prediction model sees
  int hidden = 300;                // its width (LeakyReLU 0.2)
  int epochs = 30;                 // its epochs (public code: 300 at batch 512; fewer here for
                                   // a CPU budget, its validation loss is in the run record)
  int batch_size = 512;
  double lr = 1e-3;
  double top_fraction = 0.1;       // threshold: the top share of APE, per action component...
  double top_weight = 5.0;         // ...get this weight, the rest 1
  double temperature = 1.0;        // softmax: weights = B * softmax(APE / temperature)
};

// hd: history dropout (ChauffeurNet's past-motion dropout; no public copycat baseline code).
struct HdSettings {
  double p = 0.5;  // probability that a sample's past frames are blanked (the current never)
};

// dagger: dataset aggregation with expert labels in closed loop.
struct DaggerSettings {
  int iterations = 3;            // rollout-and-retrain rounds after the expert-data policy
  int episodes = 8;              // closed-loop episodes per iteration
  double beta = 0.5;             // iteration i executes the expert with probability
  double beta_decay = 0.5;       //   beta * beta_decay^(i-1) per step, the policy otherwise
  int epochs = 2;                // training epochs after each aggregation (warm start)
  uint64_t seed = 7000;          // routes and mixing draws; never a suite's tasks
  std::string town = "town-a";   // the training town
  std::string traffic = "regular";
};

}  // namespace cd
