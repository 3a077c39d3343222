// MRCLAM import (libwheelchair/io/MrclamImport.h) on the REAL files: the bundled slice
// (datasets/mrclam: robots 3 and 4, ~50 s each, as published) always; the full Dataset 6 at
// /work/shared/datasets/mrclam/MRCLAM_Dataset6 when present (else skipped).
#include "libwheelchair/io/MrclamImport.h"

#include "../common/TestUtil.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace wheelchair::io {
namespace {

namespace fs = std::filesystem;
const std::string kSlice = std::string(WHEELCHAIR_SOURCE_DIR) + "/datasets/mrclam";
const std::string kFull = "/work/shared/datasets/mrclam/MRCLAM_Dataset6";
constexpr double kT0 = 1248444175.0;  // start of Dataset 6 (UNIX s)

TEST(MrclamImport, BundledSliceCountsSpansAndQuirks) {
  MrclamImportReport r3, r4;
  const Recording a = importMrclam(kSlice, 3, &r3), b = importMrclam(kSlice, 4, &r4);
  EXPECT_EQ(r3.commands, 2653u);
  EXPECT_EQ(r4.commands, 3166u);
  EXPECT_EQ(a.joystick.size(), r3.commands);
  EXPECT_NEAR(r3.commands_start_s - kT0, 12.886, 1e-3);
  EXPECT_NEAR(r3.ground_truth_start_s - kT0, 10.0, 0.02);
  EXPECT_LT(r3.ground_truth_end_s - kT0, 60.0);
  EXPECT_GT(r3.ground_truth, 2500u);
  EXPECT_GT(r4.ground_truth, 3000u);
  // One duplicated timestamp each (equal values), the 1 s logging gap of robot 3 at 57 s.
  EXPECT_EQ(r3.duplicate_command_times, 1u);
  EXPECT_EQ(r4.duplicate_command_times, 1u);
  EXPECT_NEAR(r3.largest_command_gap_s, 1.0, 0.02);
  EXPECT_NEAR(r3.largest_command_gap_at_s - kT0, 57.0, 0.05);
  // Once-a-second (0,0) blips.
  EXPECT_GT(r3.isolated_zero_commands, 10u);
  // Sightings mapped to subjects; robot 4's slice sees robot 2 (subject 2) and landmarks.
  EXPECT_EQ(r3.unknown_barcodes, 0u);
  EXPECT_TRUE(std::any_of(b.landmarks.begin(), b.landmarks.end(),
                          [](const LandmarkSample& s) { return s.landmark_id == 2; }));
  const auto map = landmarkMap(a);
  ASSERT_EQ(map.size(), 15u);
  EXPECT_EQ(map.front().id, 6);
  EXPECT_NEAR(map.front().x_m, 0.58831396, 1e-9);
  EXPECT_NEAR(map.back().y_m, 4.46500471, 1e-9);
}

TEST(MrclamImport, ConflictingDuplicatesAreKeptAndCounted) {
  const wheelchair::test::TempDir tmp;
  const fs::path& d = tmp.path();
  fs::copy_file(kSlice + "/Barcodes.dat", d / "Barcodes.dat", fs::copy_options::overwrite_existing);
  fs::copy_file(kSlice + "/Landmark_Groundtruth.dat", d / "Landmark_Groundtruth.dat",
                fs::copy_options::overwrite_existing);
  // Robot 4's real conflict at 205.002 s (0.067 0.023 then 0 0), with neighbours.
  std::ofstream(d / "Robot1_Odometry.dat") << "# t v w\n1248444379.990 0.067 0.023\n"
                                              "1248444380.002 0.067 0.023\n"
                                              "1248444380.002 0.000 0.000\n"
                                              "1248444380.012 0.067 0.023\n";
  std::ofstream(d / "Robot1_Groundtruth.dat") << "1248444380.0 1 2 0.5\n1248444382.1 1 2 0.5\n";
  std::ofstream(d / "Robot1_Measurement.dat") << "1248444380.0 63 2.0 0.1\n1248444380.1 99 2 0\n";
  MrclamImportReport r;
  const Recording rec = importMrclam(d.string(), 1, &r);
  EXPECT_EQ(rec.joystick.size(), 4u);  // lossless
  EXPECT_EQ(r.duplicate_command_times, 1u);
  EXPECT_EQ(r.conflicting_duplicate_commands, 1u);
  EXPECT_NEAR(r.largest_ground_truth_gap_s, 2.1, 1e-6);  // UNIX-time doubles
  EXPECT_EQ(r.unknown_barcodes, 1u);
  ASSERT_EQ(rec.landmarks.size(), 1u);
  EXPECT_EQ(rec.landmarks[0].landmark_id, 6);
}

TEST(MrclamImport, FullDataset6) {
  if (!fs::is_directory(kFull)) GTEST_SKIP() << kFull << " not present";
  const std::size_t commands[5] = {61785, 65005, 61158, 52916, 60567};
  const std::size_t dups[5] = {0, 1, 8, 10, 4}, conflicts[5] = {0, 0, 1, 3, 1};
  for (int i = 1; i <= 5; ++i) {
    MrclamImportReport r;
    const Recording rec = importMrclam(kFull, i, &r);
    EXPECT_EQ(r.commands, commands[i - 1]) << i;
    EXPECT_EQ(r.duplicate_command_times, dups[i - 1]) << i;
    EXPECT_EQ(r.conflicting_duplicate_commands, conflicts[i - 1]) << i;
    EXPECT_LT(r.largest_command_gap_s, 1.5) << i;
    EXPECT_GT(r.isolated_zero_commands, 100u) << i;
    EXPECT_LE(r.unknown_barcodes, 3u) << i;  // a few misread barcodes (not in Barcodes.dat)
    EXPECT_NEAR(r.commands_end_s - kT0, 900.1, 0.1) << i;
    if (i == 1) {
      // Ground truth ends long before the commands (the README's ~116 s; measured 128 s).
      EXPECT_GT(r.commands_end_s - r.ground_truth_end_s, 100.0);
    } else {
      EXPECT_NEAR(r.ground_truth_end_s - kT0, 900.1, 0.1) << i;
    }
    if (i == 4) EXPECT_NEAR(r.largest_ground_truth_gap_s, 2.03, 0.02);
  }
}

}  // namespace
}  // namespace wheelchair::io
