// `inspect` of real jobs made by the writer: sound jobs of every form pass, the writer's own check
// (a sample of layers decoded, the others compared in their stored form) finds what it must, profiles
// are chosen by name or by the caller, and both checksum algorithms are read. Hostile jobs:
// test_inspect_hostile.cpp. Helpers: tests/inspect_fixture.hpp.
#include "common/sha256.hpp"
#include "printer_profiles/inspect_layout.hpp"  // limitsOf
#include "printer_profiles/job_staging.hpp"     // kPartialTag
#include "tests/inspect_fixture.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cstdlib>
#include <string>

using namespace rodfab::test;
using rodfab::common::sha256Hex;

TEST_CASE("Valid small jobs of every form pass inspect", "[inspect]") {
  const fs::path dir = scratch("valid");
  writeSmallJob(dir / "bmp.zip");
  writeSmallJob(dir / "png", {ArchiveFormat::Directory, ImageFormat::Png, SupportPolicy::Explicit});
  for (const fs::path& job : {dir / "bmp.zip", dir / "png"}) {
    const InspectReport report = inspectJob(job);
    INFO(job << ": " << (report.defects.empty() ? "" : report.defects[0]));
    CHECK(report.ok());
    CHECK(report.layers == 4);
    CHECK(report.summary.profile == "stratasys-objet500-connex3");
  }
  CHECK(inspectJob(dir / "png").materials.size() == 3);
  CHECK(inspectJob(dir / "png").summary.supportPolicy == "explicit");
}

TEST_CASE("The writer's own check: a sample of layers decoded, the others compared in their stored form", "[inspect]") {
  const fs::path dir = scratch("writer-check");
  const fs::path job = dir / "job.zip";
  writeSmallJob(job, {.layers = 40});
  InspectOptions writerCheck{connex3()};
  writerCheck.decodeEvery = 32;  // layers 0, 32 and 39 decoded
  useStoredForms(writerCheck, job);
  REQUIRE(writerCheck.storedForms.size() == 80);  // Vero and Tango, 40 layers
  REQUIRE(inspectJob(job, writerCheck).ok());
  const ProfileMaterial& rigid = connex3().material(MaterialRole::Rigid);
  const std::string skipped = connex3().layerFileName(rigid, 5, ImageFormat::Bmp);
  const std::string decoded = connex3().layerFileName(rigid, 32, ImageFormat::Bmp);
  const auto files = unzip(job);
  const auto damaged = [&](const std::string& name, bool relist) {
    auto out = files;
    for (auto& [n, data] : out)
      if (n == name) data[static_cast<std::size_t>(data[10])] ^= 0x80;  // the first pixel byte (bfOffBits < 256)
    if (!relist) return out;
    const std::string digest = xxh128Hex(entryBytes(out, name));
    return tampered(std::move(out), [&](json& m) { m["files"][name]["xxh128"] = digest; });
  };

  SECTION("a bit flipped in the stored bytes of a layer that is not decoded") {
    flipStoredBit(job, skipped);
    CHECK(hasDefect(inspectJob(job, writerCheck), skipped + ": its stored bytes are not those the writer staged"));
    CHECK(hasDefect(inspectJob(job), skipped + ": is damaged"));  // inflated: invalid deflate data or a CRC error
  }
  SECTION("the same bytes under another CRC-32 in the zip's directory") {
    std::vector<RawEntry> raw;
    for (StoredEntry& e : storedEntries(job)) {
      const Bytes& contents = entryBytes(files, e.name);
      RawEntry r{e.name, std::move(e.stored), std::uint16_t(e.deflated ? 8 : 0), e.crc};
      r.compressedSize = static_cast<std::uint32_t>(r.stored.size());
      r.size = static_cast<std::uint32_t>(contents.size());
      if (r.name == skipped) r.crc ^= 1;
      raw.push_back(std::move(r));
    }
    writeRawZip(job, raw);
    CHECK(hasDefect(inspectJob(job, writerCheck), skipped + ": the zip's directory records another method, CRC-32 or size"));
    CHECK(hasDefect(inspectJob(job), skipped + ": is damaged (CRC error)"));
  }
  SECTION("the writer's method for its images is not the one the zip's directory records") {
    for (auto& [name, form] : writerCheck.storedForms) form.deflated = false;  // as if stored as they are
    CHECK(hasDefect(inspectJob(job, writerCheck), skipped + ": the zip's directory records another method, CRC-32 or size"));
  }
  SECTION("a decoded layer's image is checked against the manifest's counts") {
    rezip(job, damaged(decoded, true));
    useStoredForms(writerCheck, job);  // libzip deflated every image again
    CHECK(hasDefect(inspectJob(job, writerCheck), "the manifest says"));
    CHECK(hasDefect(inspectJob(job), "the manifest says"));
  }
  SECTION("an image changed in a layer that is not decoded, with a fresh CRC, is found by both") {
    // Until 2026-12-02 the writer's mode read such layers through their CRC-32 only and let this pass.
    rezip(job, damaged(skipped, false));
    CHECK(hasDefect(inspectJob(job, writerCheck), skipped + ": its stored bytes are not those the writer staged"));
    CHECK(hasDefect(inspectJob(job), skipped + ": checksum mismatch"));
  }
  SECTION("stored forms are not used for a folder job's files") {
    writeSmallJob(dir / "folder", {.archive = ArchiveFormat::Directory, .layers = 40});
    CHECK(inspectJob(dir / "folder", writerCheck).ok());
  }
}

// The writer's verification path itself: finalize() asks checkInterrupt once before it writes the zip
// and once after; at the second call a bit of one staged layer image is flipped in the zip it built.
TEST_CASE("The writer refuses its own job when a stored layer image changed after the zip was built", "[inspect][job]") {
  const fs::path dir = scratch("writer-tamper");
  const ProfileMaterial& rigid = connex3().material(MaterialRole::Rigid);
  for (const int layer : {5, 32}) {  // read in its stored form; decoded
    const fs::path target = dir / ("job-" + std::to_string(layer) + ".zip");
    const std::string name = connex3().layerFileName(rigid, layer, ImageFormat::Bmp);
    int calls = 0;
    const auto tamper = [&] {
      if (++calls != 2) return;
      for (const auto& e : fs::directory_iterator(dir))
        if (e.path().filename().string().starts_with("." + target.filename().string() + kPartialTag)) flipStoredBit(e.path() / "job.zip", name);
    };
    INFO("layer " << layer);
    try {
      writeSmallJob(target, {.layers = 40, .checkInterrupt = tamper});
      FAIL("the job was written");
    } catch (const std::runtime_error& e) {
      const std::string what = e.what();
      CHECK(what.find("the written job failed verification") != std::string::npos);
      const std::string why = layer == 5 ? ": its stored bytes are not those the writer staged" : ": is damaged";
      CHECK(what.find(name + why) != std::string::npos);
    }
    CHECK(calls == 2);
    CHECK_FALSE(fs::exists(target));
  }
  writeSmallJob(dir / "untouched.zip", {.layers = 40});  // the same job without the flip is written
  CHECK(inspectJob(dir / "untouched.zip").ok());
}

TEST_CASE("The profile comes from the bundled ones by name or from the caller, never from a path in the manifest",
          "[inspect][hostile]") {
  const fs::path dir = scratch("profile-name");
  writeSmallJob(dir / "job.zip");
  const auto files = unzip(dir / "job.zip");
  const HangGuard guard(60);
  // No profile can have these names: a defect, whatever the job was made with.
  for (const std::string name : {"/dev/stdin", "/dev/zero", "../../../../dev/zero", ""}) {
    rezip(dir / "hostile.zip", tampered(files, [&](json& m) { m["profile"]["name"] = name; }));
    const InspectReport report = inspectJob(dir / "hostile.zip");
    CHECK_FALSE(report.ok());
    CHECK(hasDefect(report, "hostile.zip: manifest.json: profile.name: \"" + name + "\" cannot name any printer profile ("));
  }
  // A portable name of no bundled profile: the file is never read, and the job is not checked.
  rezip(dir / "file-name.zip", tampered(files, [&](json& m) { m["profile"]["name"] = "stratasys-objet500-connex3.json"; }));
  const InspectReport fileName = inspectJob(dir / "file-name.zip");
  CHECK_FALSE(fileName.ok());
  CHECK(fileName.defects.empty());
  CHECK_THAT(fileName.notChecked, Catch::StartsWith("made with printer profile \"stratasys-objet500-connex3.json\", which is not bundled"));

  // A job written for a profile file of another name passes only when that profile is given; without
  // it the job is not checked, which is not a defect.
  Profile custom = connex3();
  custom.name = "my-connex3";
  // (The writer's own verification cannot know the profile until it passes it in InspectOptions.)
  writeSmallJob(dir / "custom.zip", {.profile = &custom, .verify = false});
  const InspectReport unchecked = inspectJob(dir / "custom.zip");
  CHECK_FALSE(unchecked.ok());
  CHECK_FALSE(unchecked.checked());
  CHECK(unchecked.defects.empty());
  CHECK_THAT(unchecked.notChecked, Catch::Contains("\"my-connex3\", which is not bundled") &&
                                       Catch::Contains("inspect --profile FILE checks it"));
  InspectOptions options;
  options.profile = custom;
  CHECK(inspectJob(dir / "custom.zip", options).ok());
  // ...and the bundled profile given explicitly for it is a mismatch, named.
  options.profile = connex3();
  CHECK(hasDefect(inspectJob(dir / "custom.zip", options), "manifest.json: profile.name: expected \"stratasys-objet500-connex3\""));
}

// Without --profile the listing stops at the most entries a job of any bundled profile can hold; a
// profile file with thinner layers makes jobs of more (until 2026-12-07 such a sound job was reported
// DEFECTIVE for its entry count).
TEST_CASE("A job of a profile file with more entries than any bundled profile allows is not checked without it",
          "[inspect]") {
  const fs::path dir = scratch("fine-layers");
  std::size_t bundledMost = 0;
  for (const std::string& name : bundledProfileNames()) bundledMost = std::max(bundledMost, limitsOf(loadProfile(name)).maxEntries);
  Profile fine = connex3();
  fine.name = "fine-connex3";
  fine.voxelSizeMm[2] = 0.01;
  const int layers = static_cast<int>(bundledMost / 2) + 50;  // two files a layer (the printer makes the support)
  REQUIRE(layers < fine.trayMm[2] / fine.voxelSizeMm[2]);
  writeSmallJob(dir / "fine.zip", {.profile = &fine, .verify = false, .layers = layers});
  auto entries = unzip(dir / "fine.zip");
  REQUIRE(entries.size() > bundledMost);
  // The manifest last, beyond where the listing stops: looked up by name.
  std::rotate(entries.begin(), entries.begin() + 1, entries.end());
  REQUIRE(entries.back().first == "manifest.json");
  rezip(dir / "manifest-last.zip", entries);
  // A folder lists in no particular order once it holds too many entries: the manifest may be beyond.
  writeSmallJob(dir / "fine", {.archive = ArchiveFormat::Directory, .profile = &fine, .verify = false, .layers = layers});
  for (const char* job : {"fine.zip", "manifest-last.zip", "fine"}) {
    INFO(job);
    const InspectReport report = inspectJob(dir / job);
    CHECK(report.defects.empty());
    CHECK_THAT(report.notChecked, Catch::StartsWith("made with printer profile \"fine-connex3\", which is not bundled") &&
                                      Catch::EndsWith("entries, more than a job of any bundled profile, and those past them were not examined"));
    InspectOptions withFile;
    withFile.profile = fine;
    const InspectReport checkedReport = inspectJob(dir / job, withFile);
    INFO((checkedReport.defects.empty() ? "" : checkedReport.defects[0]));
    CHECK(checkedReport.ok());
    CHECK(checkedReport.layers == layers);
  }
  // The same count under a bundled profile's name is a defect of the job.
  auto bundledName = entries;
  for (auto& [name, data] : bundledName)
    if (name == "manifest.json") {
      json m = json::parse(data.begin(), data.end());
      m["profile"]["name"] = "stratasys-objet500-connex3";
      const std::string text = m.dump(1);
      data.assign(text.begin(), text.end());
    }
  rezip(dir / "bundled-name.zip", bundledName);
  CHECK(hasDefect(inspectJob(dir / "bundled-name.zip"), "entries, more than a job of any bundled profile can; the rest were not listed"));
}


// The same for a manifest: without --profile it is read within the largest bundled profile's bounds,
// and one beyond them may be a profile file's job of more layers (until 2026-12-07 such a job was
// reported DEFECTIVE, "manifest.json cannot be read"). With the profile, it is a defect.
TEST_CASE("A manifest larger than any bundled profile's job is not checked without the profile file", "[inspect]") {
  const fs::path dir = scratch("large-manifest");
  ProfileLimits widest{};
  for (const std::string& name : bundledProfileNames()) {
    const ProfileLimits l = limitsOf(loadProfile(name));
    widest.maxManifestBytes = std::max(widest.maxManifestBytes, l.maxManifestBytes);
    widest.maxManifestValues = std::max(widest.maxManifestValues, l.maxManifestValues);
  }
  Profile custom = connex3();
  custom.name = "my-connex3";
  writeSmallJob(dir / "custom.zip", {.profile = &custom, .verify = false});
  const auto files = unzip(dir / "custom.zip");
  const HangGuard guard(60);
  rezip(dir / "bytes.zip", tampered(files, [&](json& m) { m["metadata"]["note"] = std::string(widest.maxManifestBytes, 'x'); }));
  rezip(dir / "values.zip", tampered(files, [&](json& m) { m["metadata"]["note"] = std::vector<int>(widest.maxManifestValues, 0); }));
  for (const auto& [job, most] : {std::pair{"bytes.zip", std::to_string(widest.maxManifestBytes) + " bytes"},
                                  std::pair{"values.zip", std::to_string(widest.maxManifestValues) + " values"}}) {
    INFO(job);
    const InspectReport report = inspectJob(dir / job);
    CHECK_FALSE(report.ok());
    CHECK(report.defects.empty());
    CHECK_THAT(report.notChecked, Catch::StartsWith("its manifest.json holds more than " + most + ", more than a job of any bundled") &&
                                      Catch::EndsWith("inspect --profile FILE checks it against that profile's file"));
    InspectOptions withFile;
    withFile.profile = custom;
    const InspectReport checkedReport = inspectJob(dir / job, withFile);
    CHECK(checkedReport.checked());
    CHECK(hasDefect(checkedReport, "manifest.json"));
    CHECK(hasDefect(checkedReport, "more than"));
  }
}

// Jobs list XXH3-128 checksums since 2026-12-02 (common/xxh128.hpp) and SHA-256 before: both are read,
// each file's row names exactly one, and a checksum of the wrong length or algorithm is refused.
TEST_CASE("File checksums: XXH3-128, or SHA-256 in older jobs, one per file, each checked", "[inspect][hostile]") {
  const fs::path dir = scratch("checksums");
  writeSmallJob(dir / "job.zip");
  const auto original = unzip(dir / "job.zip");
  const json written = manifestOf(original);
  const std::string layer = written["layers"][1]["files"].begin().value().get<std::string>();
  REQUIRE(xxh128Hex(entryBytes(original, layer)) == written["files"][layer]["xxh128"]);
  const auto inspectWith = [&](const std::function<void(json&)>& edit) {
    rezip(dir / "t.zip", tampered(original, edit));
    return inspectJob(dir / "t.zip");
  };
  SECTION("an older job, every file listed by SHA-256, passes; a wrong SHA-256 does not") {
    const auto toSha256 = [&](json& m) {
      for (auto& [name, row] : m["files"].items()) row = {{"bytes", row["bytes"]}, {"sha256", sha256Hex(entryBytes(original, name))}};
    };
    CHECK(inspectWith(toSha256).ok());
    const InspectReport wrong = inspectWith([&](json& m) {
      toSha256(m);
      m["files"][layer]["sha256"] = sha256Hex(std::string_view("another file"));
    });
    CHECK(hasDefect(wrong, layer + ": checksum mismatch"));
  }
  SECTION("a wrong XXH3-128 is a mismatch") {
    const InspectReport report = inspectWith([&](json& m) { m["files"][layer]["xxh128"] = xxh128Hex(std::string_view("x")); });
    CHECK(hasDefect(report, layer + ": checksum mismatch"));
  }
  SECTION("two checksums, none, or one of the wrong form are located") {
    const InspectReport both = inspectWith([&](json& m) { m["files"][layer]["sha256"] = sha256Hex(entryBytes(original, layer)); });
    CHECK(hasDefect(both, "files." + layer + ": holds both \"xxh128\" and \"sha256\"; expected one checksum"));
    const InspectReport none = inspectWith([&](json& m) { m["files"][layer].erase("xxh128"); });
    CHECK(hasDefect(none, "files." + layer + ": has no checksum; expected \"xxh128\""));
    const InspectReport shaLength = inspectWith([&](json& m) { m["files"][layer]["xxh128"] = sha256Hex(entryBytes(original, layer)); });
    CHECK(hasDefect(shaLength, "files." + layer + ".xxh128: expected 32 lowercase hex digits"));
  }
}

// Not a test: writes the seeds of the inspect fuzz target (tests/fuzz/seeds/inspect/), small real jobs
// made by the writer and hostile variants of them, entries stored so that mutations reach their bytes
// (named without .zip, which .gitignore keeps out of the repository).
// Run: RODFAB_SEED_DIR=tests/fuzz/seeds/inspect build/tests/test_inspect "[.make-seeds]"
TEST_CASE("Write the seeds of the inspect fuzz target", "[.make-seeds]") {
  const char* out = std::getenv("RODFAB_SEED_DIR");
  REQUIRE(out);
  const fs::path dir = scratch("seeds"), seeds = out;
  fs::create_directories(seeds);
  // Small inputs keep the kept corpus small: the previews (37 of a small job's 42 KB) become 2 x 2 PNGs,
  // re-listed, and the manifest loses the fields inspect does not read; the jobs stay sound.
  const auto shrink = [](std::vector<std::pair<std::string, Bytes>> files) {
    for (auto& [name, data] : files)
      if (name.starts_with("previews/")) data = encodePngRgb(RgbImage(2, 2, 90, 90, 90));
    return tampered(files, [&](json& m) {
      for (const auto& [name, data] : files)
        if (name.starts_with("previews/")) m["files"][name] = {{"bytes", data.size()}, {"xxh128", xxh128Hex(data)}};
      for (const char* key : {"statistics", "metadata", "calibration"}) m.erase(key);
      for (const char* key : {"origin_note", "pixel_to_design_mm", "part_voxels"}) m["frame"].erase(key);
      for (const char* key : {"row_order", "origin", "x_pixels_per_metre", "y_pixels_per_metre"}) m["image"].erase(key);
      for (const char* key : {"printer", "tray_mm", "layer_thickness_mm"}) m["profile"].erase(key);
      m["support"].erase("note");
    });
  };
  writeSmallJob(dir / "bmp.zip", {.layers = 2});
  writeSmallJob(dir / "bmp-1.zip", {.layers = 1});
  writeSmallJob(dir / "png-explicit.zip", {ArchiveFormat::Zip, ImageFormat::Png, SupportPolicy::Explicit, nullptr, true, 1});
  rezip(seeds / "job-bmp", shrink(unzip(dir / "bmp.zip")), true);
  rezip(seeds / "job-png-explicit", shrink(unzip(dir / "png-explicit.zip")), true);
  CHECK(inspectJob(seeds / "job-bmp").ok());
  CHECK(inspectJob(seeds / "job-png-explicit").ok());
  const auto files = shrink(unzip(dir / "bmp-1.zip"));
  auto raw = rawEntries(files, true);
  raw[1].mode = 0120777;  // build.txt a symbolic link
  raw[2].mode = 0010644;  // a preview a FIFO
  writeRawZip(seeds / "links-and-fifos", raw);
  raw = rawEntries(files, true);
  raw[4].stored = deflateRaw(1u << 20);  // VeroWhitePlus_0000.bmp inflates to 1 MiB, its header unchanged
  raw[4].method = 8;
  raw[4].compressedSize = static_cast<std::uint32_t>(raw[4].stored.size());
  writeRawZip(seeds / "disguised-bomb", raw);
  auto named = files;
  addListed(named, "../x", bytesOf("x"));
  addListed(named, "Build.txt", bytesOf("x"));
  writeRawZip(seeds / "unsafe-names", rawEntries(named, true));
  auto deep = files;
  for (auto& [name, data] : deep)
    if (name == "manifest.json") data = bytesOf(std::string(100, '[') + std::string(100, ']'));
  writeRawZip(seeds / "deep-manifest", rawEntries(deep, true));
  for (const auto& e : fs::directory_iterator(seeds)) CHECK(fs::file_size(e.path()) < 8192);
}
