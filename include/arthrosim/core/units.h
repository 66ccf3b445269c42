#pragma once
// Internal unit system: millimetre, second, kilogram.
//   force  = kg*mm/s^2 = 1e-3 N  (millinewton, mN)
//   stress = mN/mm^2   = 1e3 Pa  (kilopascal, kPa)
//   stiffness of a spring = mN/mm = N/m
// Scenario files use SI-friendly units per field (E in Pa, density in kg/m^3, see
// docs/scenario-format.md); these helpers convert at load and output boundaries only.

namespace arthrosim::units {

inline constexpr double kPascalToInternal = 1e-3;       // Pa -> mN/mm^2
inline constexpr double kKgPerM3ToInternal = 1e-9;      // kg/m^3 -> kg/mm^3
inline constexpr double kInternalForceToNewton = 1e-3;  // mN -> N
inline constexpr double kNewtonToInternalForce = 1e3;   // N -> mN
inline constexpr double kNewtonPerMmToInternal = 1e3;   // N/mm -> mN/mm
inline constexpr double kStandardGravityMmS2 = 9810.0;  // 9.81 m/s^2 in mm/s^2
inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kDegToRad = kPi / 180.0;

}  // namespace arthrosim::units
