#pragma once
// Internal: strict field readers for a script's YAML, bound to the file (for messages) and the
// Model (for names), and the hand-step table that turns one `{op: {...}}` item into an action.
#include <yaml-cpp/yaml.h>

#include <cstdint>
#include <initializer_list>
#include <string>
#include <vector>

#include "arthrosim/core/model.h"
#include "arthrosim/core/yaml_fields.h"
#include "script_timeline.h"

namespace arthrosim::input {

/// Purposes of the seeded noise draws (the fourth key of NoiseUniform).
enum NoisePurpose { kHesitate = 0, kHesitateLength = 1, kOvershoot = 2, kTremor = 3 };

/// Trainee noise in effect for a script: parameters, scale (0 = off) and seed.
struct NoiseCtx {
  NoiseParams p;
  double scale = 0;
  std::uint64_t seed = 1;
};

/// Reads script fields strictly; every failure throws InputError(file, line, field, message).
class Parser {
 public:
  Parser(const std::string& file, const Model& model) : file_(file), model_(model), reader_(file) {}

  /// Throws InputError naming n's line (0 if n has no position), field and msg.
  [[noreturn]] void Fail(const YAML::Node& n, const std::string& field,
                         const std::string& msg) const;
  /// Throws unless map is a map whose keys are all in allowed.
  void CheckKeys(const YAML::Node& map, const std::string& field,
                 std::initializer_list<const char*> allowed) const;
  void CheckKeys(const YAML::Node& map, const std::string& field,
                 const std::vector<const char*>& allowed) const;
  /// A finite number.
  double Num(const YAML::Node& n, const std::string& field) const;
  /// map[key] as a finite number, or def when absent.
  double Num(const YAML::Node& map, const char* key, const std::string& field, double def) const;
  /// map[key] as a number >= 0 (> 0 unless allow_zero), or def when absent.
  double Positive(const YAML::Node& map, const char* key, const std::string& field, double def,
                  bool allow_zero) const;
  /// A scalar, as written.
  std::string Str(const YAML::Node& n, const std::string& field) const;
  /// [x, y, z] of finite numbers.
  Vec3 Vec(const YAML::Node& n, const std::string& field) const;
  /// map["easing"] (linear, smoothstep or minimum_jerk), or def when absent.
  Easing Ease(const YAML::Node& map, const std::string& field, Easing def) const;
  /// A landmark name or [x, y, z], mm; portals too if allow_portal.
  Vec3 Location(const YAML::Node& n, const std::string& field, bool allow_portal) const;
  /// A portal name's position, mm.
  Vec3 Portal(const YAML::Node& n, const std::string& field) const;

  const std::string& file_;
  const Model& model_;

 private:
  YamlReader reader_;
};

/// Start time of an action, s: the cursor, or `at` if given (not earlier than the cursor, unless
/// noisy: hesitations may push a hand past a written start time, which then just starts late).
double StartTime(const Parser& ps, const YAML::Node& body, const std::string& field, double cursor,
                 bool noisy);

/// Resolves one hand's list of steps (`slot0:` or `slot1:`) into tl->hands[slot].
void BuildHand(const Parser& ps, const YAML::Node& seq, int slot, const NoiseCtx& noise,
               Timeline* tl);

}  // namespace arthrosim::input
