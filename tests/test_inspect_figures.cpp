// `inspect` and the figures a job states about itself that the rest of the job determines: the
// manifest's "statistics" block (voxels, volume and mass per material, the model's voxels) against the
// layers' counts and the profile, frame.part_voxels and frame.part_size_mm against the frame and the
// images, and the BMP file header's size field against the file. Jobs made by the writer, then altered
// by other code (libzip, nlohmann-json, byte edits here), as in test_inspect_hostile.cpp. Also: what a
// malformed manifest quotes of its bytes is escaped. Helpers: tests/inspect_fixture.hpp.
#include "tests/inspect_fixture.hpp"

#include <catch2/catch.hpp>

#include <string>

using namespace rodfab::test;

namespace {

std::uint64_t u64(const json& j) { return j.get<std::uint64_t>(); }

// The job's entries with one file's bytes changed by `edit`, and the manifest's row for it made to match.
template <class Edit>
std::vector<std::pair<std::string, Bytes>> withFileEdited(std::vector<std::pair<std::string, Bytes>> files, const std::string& name, Edit&& edit) {
  Bytes changed;
  for (auto& [n, data] : files)
    if (n == name) {
      edit(data);
      changed = data;
    }
  return tampered(std::move(files), [&](json& m) { m["files"][name] = {{"bytes", changed.size()}, {"xxh128", xxh128Hex(changed)}}; });
}

// The job's entries with manifest.json's bytes replaced by `text`, rezipped in `dir` and inspected.
InspectReport inspectedWithManifest(const fs::path& dir, std::vector<std::pair<std::string, Bytes>> files, const std::string& text) {
  for (auto& [name, data] : files)
    if (name == "manifest.json") data = bytesOf(text);
  rezip(dir / "t.zip", files);
  return inspectJob(dir / "t.zip");
}

// Every defect is printable ASCII: no raw byte of the job reaches the terminal.
void checkPrintableAscii(const InspectReport& report) {
  for (const std::string& d : report.defects)
    for (const char c : d) CHECK((static_cast<unsigned char>(c) >= 0x20 && static_cast<unsigned char>(c) < 0x7f));
}

}  // namespace

TEST_CASE("The manifest's statistics must agree with the layers' counts and the profile", "[inspect][hostile]") {
  const fs::path dir = scratch("statistics");
  writeSmallJob(dir / "job.zip");
  REQUIRE(inspectJob(dir / "job.zip").ok());
  const auto original = unzip(dir / "job.zip");
  const json stats = manifestOf(original)["statistics"];
  const std::uint64_t vero = u64(stats["materials"]["VeroWhitePlus"]["voxels"]);
  const auto inspected = [&](auto edit) {
    rezip(dir / "t.zip", tampered(original, edit));
    return inspectJob(dir / "t.zip");
  };

  SECTION("a material's voxels, one more than its layers and images hold") {
    const InspectReport report = inspected([&](json& m) { m["statistics"]["materials"]["VeroWhitePlus"]["voxels"] = vero + 1; });
    CHECK(hasDefect(report, "t.zip: manifest.json: statistics.materials.VeroWhitePlus.voxels: " + std::to_string(vero + 1) +
                                ", but the layers' counts (layers[].voxels.VeroWhitePlus), each checked against its image, add up to " +
                                std::to_string(vero)));
    CHECK(hasDefect(report, "statistics.model_voxels: "));  // the model's total no longer adds up either
  }
  SECTION("volume and mass that are not the voxels' at the profile's voxel size and density") {
    const InspectReport report = inspected([&](json& m) {
      m["statistics"]["materials"]["TangoBlackPlus"]["volume_ml"] = 999.0;
      m["statistics"]["materials"]["VeroWhitePlus"]["mass_g"] = u64(stats["materials"]["VeroWhitePlus"]["voxels"]) * 2.0;
    });
    CHECK(hasDefect(report, "manifest.json: statistics.materials.TangoBlackPlus.volume_ml: 999, but "));
    CHECK(hasDefect(report, "manifest.json: statistics.materials.VeroWhitePlus.mass_g: "));
    CHECK(report.defects.size() == 2);
  }
  SECTION("a wrong role, a material the job has not, the model's total, clamped voxels beyond the model") {
    const InspectReport report = inspected([&](json& m) {
      m["statistics"]["materials"]["VeroWhitePlus"]["role"] = "rubbery";
      m["statistics"]["materials"]["Agilus30\x1b[2J"] = m["statistics"]["materials"]["VeroWhitePlus"];
      m["statistics"]["model_voxels"] = u64(stats["model_voxels"]) + 7;
      m["statistics"]["clamped_modulus"] = {{"floor_mpa", 8.0}, {"ceiling_mpa", 190.0}, {"below_floor_voxels", u64(stats["model_voxels"])},
                                            {"above_ceiling_voxels", 1}};
    });
    CHECK(hasDefect(report, "statistics.materials.VeroWhitePlus.role: expected \"rigid\", got \"rubbery\""));
    CHECK(hasDefect(report, "statistics.materials.Agilus30\\x1b[2J: is not one of the job's materials"));
    CHECK(hasDefect(report, "statistics.model_voxels: " + std::to_string(u64(stats["model_voxels"]) + 7) +
                                ", but the model materials' voxels add up to " + std::to_string(u64(stats["model_voxels"]))));
    CHECK(hasDefect(report, "statistics.clamped_modulus: " + std::to_string(u64(stats["model_voxels"]) + 1) + " voxels clamped, more than"));
  }
  SECTION("statistics missing, or a material's row missing") {
    CHECK(hasDefect(inspected([](json& m) { m.erase("statistics"); }), "manifest.json: statistics: missing; expected an object"));
    CHECK(hasDefect(inspected([](json& m) { m["statistics"]["materials"].erase("TangoBlackPlus"); }),
                    "manifest.json: statistics.materials.TangoBlackPlus: missing; expected an object"));
  }
}

TEST_CASE("The part's box and size must agree with the frame and the images", "[inspect][hostile]") {
  const fs::path dir = scratch("part");
  writeSmallJob(dir / "job.zip");
  const auto original = unzip(dir / "job.zip");
  const auto inspected = [&](auto edit) {
    rezip(dir / "t.zip", tampered(original, edit));
    return inspectJob(dir / "t.zip");
  };
  // The small job's part: 10 x 6 x 4 voxels from (0, 0, 0).
  REQUIRE(manifestOf(original)["frame"]["part_voxels"] == json{{"min", {0, 0, 0}}, {"max", {9, 5, 3}}});

  SECTION("a part size the box does not have (the review's 999 mm part passed)") {
    const InspectReport report = inspected([](json& m) { m["frame"]["part_size_mm"] = {999.0, 999.0, 999.0}; });
    CHECK(hasDefect(report, "manifest.json: frame.part_size_mm: 999 mm along x, but frame.part_voxels spans 10 voxels of 0.0423 mm = 0.423 mm"));
  }
  SECTION("a box that is not the frame's: the layers and rows it would give are not the job's") {
    const InspectReport report = inspected([](json& m) {
      m["frame"]["part_voxels"]["max"] = {9, 5, 4};
      m["frame"]["part_size_mm"][2] = 5 * 0.03;
    });
    CHECK(hasDefect(report, "manifest.json: layer_count: 4, but a part of frame.part_voxels from (0, 0, 0) to (9, 5, 4)"));
  }
  SECTION("a box the images leave: shifted along x, with the part size and frame to match") {
    const InspectReport report = inspected([](json& m) {
      m["frame"]["part_voxels"] = {{"min", {8, 0, 0}}, {"max", {17, 5, 3}}};
    });
    CHECK(hasDefect(report, "VeroWhitePlus: the images hold voxels from (0, "));
    CHECK(hasDefect(report, "outside the part's box in manifest.json's frame.part_voxels"));
  }
  SECTION("part_voxels missing or malformed") {
    CHECK(hasDefect(inspected([](json& m) { m["frame"].erase("part_voxels"); }), "manifest.json: frame.part_voxels: missing; expected an object"));
    CHECK(hasDefect(inspected([](json& m) { m["frame"]["part_voxels"]["min"] = {0, 9, 0}; }),
                    "manifest.json: frame.part_voxels: min is above max along y"));
    CHECK(hasDefect(inspected([](json& m) { m["frame"].erase("part_size_mm"); }), "manifest.json: frame.part_size_mm: missing"));
  }
}

TEST_CASE("A BMP layer whose file header misstates its size is a defect, even when the manifest agrees", "[inspect][hostile]") {
  const fs::path dir = scratch("bmp-size");
  writeSmallJob(dir / "job.zip");
  const auto original = unzip(dir / "job.zip");
  const std::string layer = "VeroWhitePlus_0001.bmp";
  const std::size_t size = entryBytes(original, layer).size();
  SECTION("the size field says 1,000,000 bytes") {
    rezip(dir / "t.zip", withFileEdited(original, layer, [](Bytes& b) {
            b[2] = 0x40, b[3] = 0x42, b[4] = 0x0f, b[5] = 0;  // 1000000, little-endian
          }));
    CHECK(hasDefect(inspectJob(dir / "t.zip"),
                    "t.zip: " + layer + ": BMP file header says the file is 1000000 bytes; it is " + std::to_string(size)));
  }
  SECTION("four bytes appended after the rows, the size field left as it was") {
    rezip(dir / "t.zip", withFileEdited(original, layer, [](Bytes& b) { b.insert(b.end(), 4, 0); }));
    CHECK(hasDefect(inspectJob(dir / "t.zip"),
                    "t.zip: " + layer + ": BMP file header says the file is " + std::to_string(size) + " bytes; it is " + std::to_string(size + 4)));
  }
}

TEST_CASE("A malformed manifest's quoted bytes are escaped once: no raw byte reaches the terminal, no escape is escaped again",
          "[inspect][hostile]") {
  const fs::path dir = scratch("manifest-bytes");
  writeSmallJob(dir / "job.zip");
  const auto files = unzip(dir / "job.zip");
  const InspectReport report = inspectedWithManifest(dir, files, "{\"format\": tru\xc2\x9b\xff}");
  REQUIRE(hasDefect(report, "t.zip: manifest.json: cannot be read: malformed JSON at line 1, column "));
  checkPrintableAscii(report);
  CHECK(hasDefect(report, "last read: '\"format\": tru\\xc2'"));
  for (const std::string& d : report.defects) CHECK(d.find("\\x5cx") == std::string::npos);
  // A UTF-8 letter (which parseJsonStrict's messages keep) in inspect's ASCII form, as the fuzz target requires.
  const InspectReport accented = inspectedWithManifest(dir, files, "{\"format\": \"caf\xc3\xa9\" x}");
  CHECK(hasDefect(accented, "caf\\xc3\\xa9"));
  checkPrintableAscii(accented);
}
