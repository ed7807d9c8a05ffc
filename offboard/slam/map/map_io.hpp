// Saving and loading the local map (keyframes with their features and thumbnails, map points with
// observations, culled-keyframe links), so that a later run relocalises in it and reports poses in
// its world frame.
//
// File format (all little-endian, written field by field, never a struct memcpy):
//   "RGBDQMAP" | u32 version (kMapFileVersion) | camera fx fy cx cy bf (f64) width height (i32)
//   | detector kind (u8: 0 sift, 1 surf, 2 orb) | descriptor cols (i32) and OpenCV type (i32)
//   | keyframes | points | culled keyframes | loop edges (v2) | u64 map corrections (v3) | u64
//   FNV-1a hash of every byte before it.
// A file of another version, another camera or detector, a bad hash (corrupt or truncated) or
// counts beyond the sanity bounds is refused with a message; loading never trusts a size field
// before checking it against the bytes left.
//
// Stateless; thread-safe for distinct files.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "slam/map/map.hpp"

namespace rgbdquad::slam {

/// Version 2 added the loop-closure edges after the culled keyframes; version 3 the count of map
/// corrections (SharedMap::corrections) the poses are expressed after, so that a session resumed
/// from a checkpoint declares a correction made after the checkpoint as one (older versions are
/// refused).
constexpr std::uint32_t kMapFileVersion = 3;

/// FNV-1a 64-bit hash of `n` bytes: the integrity check of the map and vocabulary files.
std::uint64_t fnv1a64(const std::uint8_t* data, std::size_t n);

struct MapFileContext {
  CameraModel camera;
  FeatureOptions features;  ///< detector kind must match; used to rebuild keypoint sigmas
};

/// Writes `map` to `path` (through a temporary file renamed into place: a crash never leaves a
/// half-written map under the name). `map_corrections`: the loop corrections applied to `map`
/// (SharedMap::corrections). False with `error` on I/O failure.
bool save_map(const std::string& path, const SlamMap& map, const MapFileContext& context,
              std::string* error, std::uint64_t map_corrections = 0);

/// The file at `path` is a map file of this version, whole (checksum): what can be told without
/// the camera and detector it must match (load_map checks those). False with `error` else.
bool check_map_file(const std::string& path, std::string* error);

/// Reads a map written by save_map for the same camera and detector. nullopt with `error`
/// otherwise. `map_corrections` (if given) receives the count saved with it.
std::optional<SlamMap> load_map(const std::string& path, const MapFileContext& context,
                                std::string* error, std::uint64_t* map_corrections = nullptr);

}  // namespace rgbdquad::slam
