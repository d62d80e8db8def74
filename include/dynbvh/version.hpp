// SPDX-License-Identifier: MIT
/// @file version.hpp
/// dynbvh's version (semantic versioning); CMake's configure step fails when these differ from
/// project(VERSION) in CMakeLists.txt.
#pragma once

/// Major version (incompatible API changes).
#define DYNBVH_VERSION_MAJOR 0
/// Minor version (compatible additions).
#define DYNBVH_VERSION_MINOR 1
/// Patch version (fixes only).
#define DYNBVH_VERSION_PATCH 0
/// MAJOR * 10000 + MINOR * 100 + PATCH, for `#if DYNBVH_VERSION >= 100` style checks.
#define DYNBVH_VERSION (DYNBVH_VERSION_MAJOR * 10000 + DYNBVH_VERSION_MINOR * 100 + DYNBVH_VERSION_PATCH)
