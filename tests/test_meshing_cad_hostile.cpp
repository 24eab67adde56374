// rods-from-cad on hostile files: what OpenCASCADE would crash or hang on is refused, naming the line
// or entity; whatever becomes of the CAD reader process is an error naming the file.
#include "meshing/cad_reader.hpp"
#include "meshing/meshing.hpp"
#include "tests/meshing/cad_test_support.hpp"

#include <catch2/catch.hpp>

#include <cstring>
#include <functional>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <unistd.h>

using namespace rodfab;
using namespace rodfab::cad_test;

TEST_CASE("the hostile-file fixture reads as a valid spline", "[meshing][cad][hostile]") {
  const fs::path file = scratch("fixture.step");
  std::ofstream(file) << stepModel(splineData());
  const meshing::CadRods result = meshing::rodsFromCad(file, {});
  REQUIRE(result.structure.rods.size() == 1);
  CHECK(result.structure.rods[0].centerline().degree() == 3);
}

TEST_CASE("STEP files OpenCASCADE would crash on are refused, naming the entity or line", "[meshing][cad][hostile]") {
  using Catch::Contains;
  // Failures OpenCASCADE records while loading: the transfer would follow the null handles they leave.
  CHECK_THAT(cadError("missing.step", stepModel(splineData("(#9999,#19,#20,#21,#22,#23)"))),
             Contains("malformed: entity #17 (B_SPLINE_CURVE_WITH_KNOTS)") && Contains("unresolved"));
  CHECK_THAT(cadError("noargs.step", stepModel(splineData() + "#31 = B_SPLINE_CURVE_WITH_KNOTS();\n"
                                                              "#32 = GEOMETRIC_CURVE_SET('',(#31));\n")),
             Contains("entity #31 (B_SPLINE_CURVE_WITH_KNOTS)") && Contains("Count of Parameters"));
  CHECK_THAT(cadError("wrongtype.step", stepModel(splineData("(#13,#19,#20,#21,#22,#23)"))),
             Contains("entity #17 (B_SPLINE_CURVE_WITH_KNOTS)") && Contains("illegal type"));
  CHECK_THAT(cadError("selfref.step", stepModel(splineData("(#17,#19,#20,#21,#22,#23)"))), Contains("entity #17"));
  // A reference cycle: the transfer recursed until the stack ran out.
  CHECK_THAT(cadError("cycle.step", stepModel(splineData("(#18,#19,#20,#21,#22,#23)", "3", "(#15)"))),
             Contains("entity #15 (GEOMETRIC_CURVE_SET) refers to itself"));
  CHECK_THAT(cadError("cycle2.step", stepModel(splineData() + "#31 = GEOMETRIC_CURVE_SET('',(#16,#32));\n"
                                                              "#32 = GEOMETRIC_CURVE_SET('',(#31));\n")),
             Contains("refers to itself"));
  // Degrees and pole counts Geom_BSplineCurve refuses, checked before the converters index by them.
  CHECK_THAT(cadError("degree.step", stepModel(splineData("(#18,#19,#20,#21,#22,#23)", "30"))),
             Contains("B-spline entity #17 (B_SPLINE_CURVE_WITH_KNOTS): degree 30, expected 1 to 25"));
  CHECK_THAT(cadError("poles.step", stepModel(splineData("(#18,#19,#20,#21,#22,#23)", "9"))),
             Contains("6 control points, expected at least degree + 1 = 10"));
  // What the parser itself cannot take, found in the text.
  const std::string deep = std::string(100'000, '(') + std::string(100'000, ')');
  CHECK_THAT(cadError("deep.step", stepModel(splineData("(#18,#19,#20,#21,#22,#23)", "3", "(#16," + deep + ")"))),
             Contains("line 22: lists nested deeper than 64 levels"));
  CHECK_THAT(cadError("hugeid.step", stepModel(splineData("(#18,#99999999999999999999,#20,#21,#22,#23)"))),
             Contains("line 24: an entity id above 999999999"));
  std::string longList = "(#16";
  for (int i = 0; i < 100'000; ++i) longList += ",#16";
  CHECK_THAT(cadError("longlist.step", stepModel(splineData("(#18,#19,#20,#21,#22,#23)", "3", longList + ")"))),
             Contains("line 22: a list of more than 100000 elements"));
  // Empty lists where STEP requires elements: OpenCASCADE's load check and transfer crash on them. An
  // entity without parameters (every file's LENGTH_UNIT()) is not such a list.
  std::string noKnots = splineData();
  noKnots.replace(noKnots.find("(0.,0.3,0.45,1.)"), 16, "( )");
  CHECK_THAT(cadError("noknots.step", stepModel(noKnots)), Contains("line 24: an empty list in a B_SPLINE_CURVE_WITH_KNOTS"));
  std::string noDirection = stepModel(splineData());
  noDirection.replace(noDirection.find("DIRECTION('',(0.,0.,1.))"), 24, "DIRECTION('',())");
  CHECK_THAT(cadError("nodirection.step", noDirection), Contains("an empty list in a DIRECTION, where STEP requires at least one"));
  // An id defined twice: OpenCASCADE kept the first and said nothing (a box's corner left open, exit 0).
  // References to an id (inside lists) are not definitions.
  CHECK_THAT(cadError("twice.step", stepModel(splineData() + "#19 = CARTESIAN_POINT('',(5.,5.,5.));\n")),
             Contains("entity #19 is defined a second time"));
  CHECK_THAT(cadError("twice-commented.step", stepModel(splineData() + "#19 /* moved */ = CARTESIAN_POINT('',(5.,5.,5.));\n")),
             Contains("entity #19 is defined a second time"));
  CHECK(meshing::rodsFromCad([&] {
          const fs::path file = scratch("references.step");
          std::ofstream(file) << stepModel(splineData() + "#31 = GEOMETRIC_CURVE_SET('',(#17, #17));\n");
          return file;
        }(), {}).structure.rods.size() >= 1);
  // Text in strings and comments is not counted.
  const std::string hostile = "#99999999999999999999 " + std::string(100, '(');
  std::string named = splineData();
  named.replace(named.find("''"), 2, "'" + hostile + "'");
  const fs::path quoted = scratch("quoted.step");
  std::ofstream(quoted) << stepModel("/* " + hostile + " */\n" + named);
  CHECK(meshing::rodsFromCad(quoted, {}).structure.rods.size() == 1);
}

namespace {

// The text of the IGES file `file` with the data columns (1-64) of its first parameter record that
// starts with `prefix`, trailing spaces trimmed, replaced by what `edit` makes of them (padded back).
std::string withRecordEdited(const fs::path& file, const std::string& prefix, const std::function<std::string(std::string)>& edit) {
  std::ifstream in(file);
  std::string text, line;
  bool changed = false;
  while (std::getline(in, line)) {
    if (!changed && line.rfind(prefix, 0) == 0) {
      std::string data = line.substr(0, 64);
      data = edit(data.erase(data.find_last_not_of(' ') + 1));
      REQUIRE(data.size() <= 64);
      line = data + std::string(64 - data.size(), ' ') + line.substr(64);
      changed = true;
    }
    text += line + "\n";
  }
  REQUIRE(changed);
  return text;
}

// The IGES file's first line record (110,X1,Y1,Z1,X2,Y2,Z2;) with its second end, from X2 on, replaced
// by what `edit` makes of the first end's text ("0.,0.,30.") and the second's ("0.,20.,30.;").
std::string withSecondEndOfLine(const fs::path& file,
                                const std::function<std::string(const std::string& firstEnd, const std::string& secondEnd)>& edit) {
  return withRecordEdited(file, "110,", [&](const std::string& data) {
    std::size_t at = 4;
    for (int k = 0; k < 3; ++k) at = data.find(',', at) + 1;
    return data.substr(0, at) + edit(data.substr(4, at - 5), data.substr(at));
  });
}

// The test spline's record "126,5,3,..." (upper index 5, degree 3) with its counts replaced by
// `counts` ("126,5,1000000,"); six weights written as integers make room in its 64 data columns.
std::string splineRecordWithCounts(const fs::path& valid, const std::string& counts) {
  return withRecordEdited(valid, "126,5,3,", [&](std::string data) {
    const std::size_t weights = data.find("1.,1.,1.,1.,1.,1.,");
    REQUIRE(weights != std::string::npos);
    data.replace(weights, 18, "1,1,1,1,1,1,");
    return data.replace(0, 8, counts);
  });
}

}  // namespace

TEST_CASE("an IGES B-spline of an impossible degree is refused before OpenCASCADE loads it", "[meshing][cad][hostile]") {
  const fs::path valid = scratch("valid.igs");
  testing::writeIges(testing::edgeOf(testing::testSpline()), valid);
  CHECK_THAT(cadError("degree.igs", splineRecordWithCounts(valid, "126,5,1000000,")),
             Catch::Contains("malformed IGES B-spline curve (type 126): degree 1000000, expected 1 to 25"));
}

TEST_CASE("an IGES B-spline whose record holds fewer values than its counts need is refused before loading", "[meshing][cad][hostile]") {
  // The record claims upper index 95 (96 poles: 493 values) and holds 46; OpenCASCADE's reader left
  // arrays null that the curve's Init then read (a SIGSEGV, found by mutate_cad.py).
  const fs::path valid = scratch("valid-count.igs");
  testing::writeIges(testing::edgeOf(testing::testSpline()), valid);
  CHECK_THAT(cadError("short-record.igs", splineRecordWithCounts(valid, "126,95,3,")),
             Catch::Contains("malformed IGES B-spline curve (type 126): 46 values where its counts need at least 493"));
  CHECK(meshing::rodsFromCad(valid, {}).structure.rods.size() == 1);
}

TEST_CASE("rods-from-cad never builds a design that validate refuses", "[meshing][cad][hostile]") {
  using Catch::Contains;
  // Coordinates beyond +-1e9 mm, each named by its edge and the entity it came from.
  CHECK_THAT(cadError("far.step", stepModel(splineData("(#18,#19,#20,#21,#22,#23)", "3", "(#16)", "1.E12"))),
             Contains("edge 0 (entity #16 (TRIMMED_CURVE)): a control point at (1e+12, 5, 2) mm, beyond the +-1e9 mm"));
  CHECK_THAT(cadError("line.step", stepModel("#15 = GEOMETRIC_CURVE_SET('',(#16));\n#16 = LINE('',#12,#17);\n"
                                             "#17 = VECTOR('',#13,1.);\n")),
             Contains("edge 0 (entity #16 (LINE)): a control point at (0, 0, -2e+100) mm"));
  const std::string huge = cadError("circle.step", stepModel(circleData("1.E300")));
  CHECK_THAT(huge, Contains("beyond the +-1e9 mm"));
  CHECK(huge.size() < 300);  // numbers in a short format, not 300 digits
  CHECK_THAT(cadError("unit.step", stepModel(splineData(), "( CONVERSION_BASED_UNIT('BIG',#40) LENGTH_UNIT() NAMED_UNIT(#41) );\n"
                                             "#40 = LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(1.E300),#42);\n"
                                             "#41 = DIMENSIONAL_EXPONENTS(1.,0.,0.,0.,0.,0.,0.);\n"
                                             "#42 = ( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.) )")),
             Contains("beyond the +-1e9 mm"));
  // Zero-length centerlines, found by the design file's own checks.
  const std::string zero = "degenerate centerline: its length is zero";
  CHECK_THAT(cadError("r0.step", stepModel(circleData("0."))), Contains("edge 0 (entity #16 (TRIMMED_CURVE)): " + zero));
  // Checked before the rod's frame is built on it (a zero tangent has no normal).
  meshing::CadRodOptions ellipse;
  ellipse.section = geometry::Section::ellipse(1, 2);
  CHECK_THAT(cadError("r0e.step", stepModel(circleData("0.")), ellipse), Contains("edge 0 (entity #16 (TRIMMED_CURVE)): " + zero));
  // A line 0.0005 mm long: both its ends merge onto one point (joint tolerance 0.001 mm).
  CHECK_THAT(cadError("short.step", stepModel("#15 = GEOMETRIC_CURVE_SET('',(#16));\n"
                                              "#16 = TRIMMED_CURVE('',#17,(PARAMETER_VALUE(0.)),(PARAMETER_VALUE(0.0005)),"
                                              ".T.,.PARAMETER.);\n"
                                              "#17 = LINE('',#12,#18);\n#18 = VECTOR('',#14,1.);\n")),
             Contains("edge 0 (entity #16 (TRIMMED_CURVE)): " + zero));
  std::string same = splineData();
  for (const char* p : {"0.,0.,0.", "10.,5.,2.", "20.,-5.,6.", "30.,8.,1.", "38.,0.,-4.", "45.,3.,0."})
    for (std::size_t at; (at = same.find(p)) != std::string::npos;) same.replace(at, std::strlen(p), "1.,1.,1.");
  CHECK_THAT(cadError("same.step", stepModel(same)), Contains(zero));
  CHECK_THAT(cadError("unit0.step", stepModel(splineData(), "( CONVERSION_BASED_UNIT('ZERO',#40) LENGTH_UNIT() NAMED_UNIT(#41) );\n"
                                              "#40 = LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(0.),#42);\n"
                                              "#41 = DIMENSIONAL_EXPONENTS(1.,0.,0.,0.,0.,0.,0.);\n"
                                              "#42 = ( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.) )")),
             Contains(zero));
}

namespace {

// A stand-in for rodfab-cad-reader: a shell script with `body`, made executable.
fs::path fakeReader(const std::string& name, const std::string& body) {
  const fs::path path = scratch(name);
  std::ofstream(path) << "#!/bin/sh\n" << body << "\n";
  fs::permissions(path, fs::perms::owner_all);
  return path;
}

// The error of rodsFromCadThrough, checked to be writeDesignFromCadThrough's too, which writes nothing.
std::string errorThrough(const fs::path& helper, const fs::path& model) {
  const std::string kept = meshErrorOf(model, [&] { meshing::detail::rodsFromCadThrough(helper, model, {}); });
  const fs::path design = scratch("never-written.json");
  CHECK(meshErrorOf(model, [&] { meshing::detail::writeDesignFromCadThrough(helper, model, {}, design, "d"); }) == kept);
  CHECK_FALSE(fs::exists(design));
  return kept;
}

}  // namespace

TEST_CASE("whatever becomes of the CAD reader process is an error naming the file", "[meshing][cad][hostile]") {
  using Catch::Contains;
  // A report of 2 rods, and a design of one.
  const std::string kReport = R"({"edges": 2, "rods": 2, "joints": 0, "skipped_degenerate": 0, "largest_end_move_mm": 0,)"
                              R"( "approximated": 0, "largest_approximation_error_mm": 0, "untranslated": 0, "first_untranslated": "",)"
                              R"( "smallest_bend_radius_mm": null, "rods_bent_tighter_than_section": 0})";
  const std::string kDesign = R"({"format": "rodfab.design/1", "rods": [{"name": "edge-0", "centerline": {"degree": 1,)"
                              R"( "knots": [0, 0, 1, 1], "points": [[0, 0, 0], [5, 0, 0]]}, "section": {"shape": "circle",)"
                              R"( "diameter": 1}, "modulus": 100}]})";
  const fs::path model = scratch("stand-in.step");
  std::ofstream(model) << "ISO-10303-21;\n";
  CHECK_THAT(errorThrough(fakeReader("segv.sh", "kill -SEGV $$"), model),
             Contains("the CAD reader (OpenCASCADE) crashed on this file (signal 11"));
  CHECK_THAT(errorThrough(fakeReader("abort.sh", "echo 'terminate called' >&2; kill -ABRT $$"), model),
             Contains("(signal 6") && Contains("(it said: terminate called)"));
  CHECK_THAT(errorThrough(fakeReader("exit3.sh", "echo boom >&2; exit 3"), model),
             Contains("stopped with exit code 3 and no answer (it said: boom)"));
  CHECK(errorThrough(fakeReader("error.sh", "printf '{\"error\": \"edge 2: a curve of degree 9\"}' >&3"), model) ==
        model.string() + ": edge 2: a curve of degree 9");
  CHECK_THAT(errorThrough(fakeReader("garbage.sh", "echo 'not json' >&3"), model), Contains("answer is not JSON"));
  CHECK_THAT(errorThrough(fakeReader("half.sh", "printf '{\"design\": {' >&3; kill -KILL $$"), model),
             Contains("the CAD reader was killed (signal 9, Killed), not by rodfab: the system may have run out of memory"));
  CHECK_THAT(errorThrough(fakeReader("nodesign.sh", "echo '{\"report\": {}}' >&3"), model), Contains("has no design and report"));
  CHECK_THAT(errorThrough(fakeReader("baddesign.sh",
                                     "echo '{\"design\": {\"format\": \"rodfab.design/1\", \"rods\": 7}, \"report\": " + kReport + "}' >&3"),
                          model),
             Contains("the CAD reader's design is not valid"));
  CHECK_THAT(errorThrough(fakeReader("badreport.sh", "echo '{\"design\": {}, \"report\": {\"edges\": -1}}' >&3"), model),
             Contains("the CAD reader's report is malformed"));
  CHECK_THAT(errorThrough(fakeReader("liar.sh", "echo '{\"design\": " + kDesign + ", \"report\": " + kReport + "}' >&3"), model),
             Contains("the CAD reader's report does not match its design"));
  CHECK_THAT(errorThrough(scratch("no-such-reader"), model), Contains("did not start (No such file or directory)"));
  // A reader that never answers is waited for, not polled to death: the answer comes when it exits.
  CHECK_THAT(errorThrough(fakeReader("slow.sh", "sleep 0.3; exit 0"), model), Contains("answer is not JSON"));
}

TEST_CASE("the CAD reader's arguments carry the options exactly", "[meshing][cad]") {
  meshing::detail::CadReaderRequest request{"a b/c.step", {}, 123456789012345ULL, 4194304};
  request.options.section = geometry::Section::ellipse(0.1, 1.0 / 3.0);
  request.options.caps = geometry::CapStyle::Flat;
  request.options.modulusMpa = 2.0 / 7.0;
  request.options.jointTolerance = 1e-9 * 3.0;
  const meshing::detail::CadReaderRequest back = meshing::detail::fromReaderArguments(meshing::detail::readerArguments(request));
  CHECK(back.file == request.file);
  CHECK(back.options.section.shape == geometry::SectionShape::Ellipse);
  CHECK(back.options.section.width == 0.1);
  CHECK(back.options.section.height == 1.0 / 3.0);
  CHECK(back.options.caps == geometry::CapStyle::Flat);
  CHECK(back.options.modulusMpa == 2.0 / 7.0);
  CHECK(back.options.jointTolerance == 1e-9 * 3.0);
  CHECK(back.memoryBudget == request.memoryBudget);
  CHECK(back.parentProcess == 4194304);
  std::vector<std::string> wrong = meshing::detail::readerArguments(request);
  wrong[1] = "hexagon";
  CHECK_THROWS_AS(meshing::detail::fromReaderArguments(wrong), std::invalid_argument);
  wrong.pop_back();
  CHECK_THROWS_AS(meshing::detail::fromReaderArguments(wrong), std::invalid_argument);
}

TEST_CASE("an IGES loop whose edge index is past its edge list is refused, naming the loop", "[meshing][cad][hostile]") {
  // A box in IGES's B-rep form: its loops (type 508) refer to the edge list (504) by index, read
  // unchecked by OpenCASCADE's transfer (a SIGSEGV for an index past the list, found by mutate_cad.py).
  const fs::path valid = scratch("box.igs");
  testing::writeIges(testing::box(10, 20, 30), valid);
  // 508,N,TYPE,EDGE LIST,INDEX,...: the first edge's index becomes 99.
  const std::string text = withRecordEdited(valid, "508,", [](std::string data) {
    const std::size_t at = data.find(',', data.find(',', data.find(',', data.find(',') + 1) + 1) + 1) + 1;
    return data.replace(at, data.find(',', at) - at, "99");
  });
  CHECK_THAT(cadError("badloop.igs", text),
             Catch::Contains("malformed: entity D") && Catch::Contains("Loop): edge 1 refers to item 99 of a list of 12"));
  CHECK(meshing::rodsFromCad(valid, {}).structure.rods.size() == 12);
}

TEST_CASE("an IGES loop's edge of a type other than its list's is refused, naming the loop", "[meshing][cad][hostile]") {
  // The type says what the list is (0 edges, 1 vertices); OpenCASCADE's transfer trusts it (a SIGSEGV
  // for a type of 100 on an edge list, found by mutate_cad.py).
  const fs::path valid = scratch("box.igs");
  testing::writeIges(testing::box(10, 20, 30), valid);
  for (const std::string type : {"100", "1", "-1"}) {
    // 508,N,TYPE,...: the first edge's type.
    const std::string text = withRecordEdited(valid, "508,", [&](std::string data) {
      const std::size_t at = data.find(',', data.find(',') + 1) + 1;
      return data.replace(at, data.find(',', at) - at, type);
    });
    CHECK_THAT(cadError("badtype.igs", text), Catch::Contains("Loop): edge 1 is of type " + type + " on an edge list (expected type 0"));
  }
}

TEST_CASE("an IGES edge on a line of zero length is refused, naming the edge list", "[meshing][cad][hostile]") {
  // The box with its first line (type 110: 110,X1,Y1,Z1,X2,Y2,Z2;) ending where it starts: OpenCASCADE's
  // loop transfer dereferences the null wire it makes of that edge (a SIGSEGV, found by mutate_cad.py).
  const fs::path valid = scratch("box-lines.igs");
  testing::writeIges(testing::box(10, 20, 30), valid);
  const std::string text = withSecondEndOfLine(valid, [](const std::string& firstEnd, const std::string&) { return firstEnd + ";"; });
  CHECK_THAT(cadError("zero-line.igs", text), Catch::Contains("malformed: entity D") && Catch::Contains("EdgeList): edge ") &&
                                                  Catch::Contains("'s curve is a line of zero length"));
  CHECK(meshing::rodsFromCad(valid, {}).structure.rods.size() == 12);
}

TEST_CASE("an IGES line OpenCASCADE would take as infinite, and a loop edge's curves past its record, are refused", "[meshing][cad][hostile]") {
  // Found by mutate_cad.py on the box's B-rep, each a SIGSEGV in OpenCASCADE: a line (110,X1,Y1,Z1,X2,
  // Y2,Z2;) ending at x = -1e308 (OpenCASCADE's infinity is 2e100), and a loop edge's count K of
  // parameter-space curves (508,N,TYPE,LIST,INDEX,ORIENT,K,...) of 3 in a record without them.
  const fs::path valid = scratch("box-far.igs");
  testing::writeIges(testing::box(10, 20, 30), valid);
  const std::string far = withSecondEndOfLine(
      valid, [](const std::string&, const std::string& secondEnd) { return "-1.E308" + secondEnd.substr(secondEnd.find(',')); });
  CHECK_THAT(cadError("far-line.igs", far), Catch::Contains("Line): a line ending at (-1e+308, ") &&
                                                 Catch::Contains("beyond +-1e15 in the file's unit"));
  const std::string three = "3";
  const std::string curves = withRecordEdited(valid, "508,", [&](std::string data) {
    std::size_t at = 0;
    for (int k = 0; k < 6; ++k) at = data.find(',', at) + 1;  // the first edge's K
    return data.replace(at, data.find(',', at) - at, three);
  });
  CHECK_THAT(cadError("loop-curves.igs", curves),
             Catch::Contains(": malformed IGES Loop (type 508): edge ") && Catch::Contains(" past the record"));
  CHECK(meshing::rodsFromCad(valid, {}).structure.rods.size() == 12);
}

TEST_CASE("an IGES B-rep record whose count runs past its values, or a record numbered with garbage, is refused", "[meshing][cad][hostile]") {
  // Found by mutate_cad.py on the box's B-rep, each a SIGSEGV in OpenCASCADE: a face (510,SURFACE,N,
  // OUTER,LOOPS...) whose loop count N is "E5", and a directory entry's sequence number "000;017".
  const fs::path valid = scratch("box-counts.igs");
  testing::writeIges(testing::box(10, 20, 30), valid);
  const auto faceWithCount = [&](const std::string& count) {
    return withRecordEdited(valid, "510,", [&](std::string data) {
      const std::size_t at = data.find(',', 4) + 1;
      return data.replace(at, data.find(',', at) - at, count);
    });
  };
  CHECK_THAT(cadError("face-e5.igs", faceWithCount("E5")),
             Catch::Contains("malformed IGES Face (type 510): its count of loops 'E5' is not a whole number"));
  CHECK_THAT(cadError("face-many.igs", faceWithCount("100000")),
             Catch::Contains("malformed IGES Face (type 510): 100000 loops need at least 100004 values; the record holds 5"));
  std::ifstream in(valid);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t directory = text.find("D0000001\n");
  REQUIRE(directory != std::string::npos);
  text.replace(directory + 1, 7, "000;001");
  CHECK_THAT(cadError("sequence.igs", text),
             Catch::Contains("malformed IGES record: its sequence number (columns 74-80) '000;001' is not a number"));
  CHECK(meshing::rodsFromCad(valid, {}).structure.rods.size() == 12);
}

TEST_CASE("an IGES Global section that does not give its unit is refused, not read as inches", "[meshing][cad][hostile]") {
  // A Global section cut short after a string of length -5 made OpenCASCADE take the unit as IGES's
  // default, inches, without a word: a 10 mm line became a 254 mm rod.
  const fs::path valid = scratch("valid-global.igs");
  testing::writeIges(testing::edgeOf(testing::testSpline()), valid);
  std::ifstream in(valid, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // `from` replaced by `to` in the file, the line's columns kept (spaces before column 73 taken out or
  // put in).
  const auto changed = [&](const std::string& name, const std::string& from, const std::string& to) {
    std::string t = text;
    const std::size_t at = t.find(from);
    REQUIRE(at != std::string::npos);
    t.replace(at, from.size(), to);
    const std::size_t column73 = t.find_first_of("SGDPT", t.find('\n', at) - 8);  // the section letter
    if (to.size() < from.size()) t.insert(column73, from.size() - to.size(), ' ');
    else t.erase(column73 - (to.size() - from.size()), to.size() - from.size());
    const fs::path file = scratch(name);
    std::ofstream(file, std::ios::binary) << t;
    return meshErrorOf(file, [&] { meshing::rodsFromCad(file, {}); });
  };
  // OpenCASCADE writes the scale, the unit flag and the unit's name as ",1.,2,2HMM,".
  CHECK_THAT(changed("no-flag.igs", ",1.,2,2HMM,", ",1.,,2HMM,"),
             Catch::Contains("line 2: the IGES Global section's unit flag (its value 14) is not given, expected 1 to 11"));
  CHECK_THAT(changed("word-flag.igs", ",1.,2,2HMM,", ",1.,x,2HMM,"), Catch::Contains("unit flag (its value 14) is 'x'"));
  CHECK_THAT(changed("cut.igs", ",,31HOpen CASCADE IGES processor 7.6,", ",,-5Hhunt,;"),
             Catch::Contains("line 2: the IGES Global section ends before its unit flag (value 14)"));
  // A name counted in characters rather than UTF-8 bytes, before the unit: the unit is still found.
  CHECK(changed("utf8.igs", "13HFilename.iges", "13HFilen\xc3\xa4me.iges") == "no error");
  CHECK(meshing::rodsFromCad(valid, {}).structure.rods.size() == 1);
}

TEST_CASE("a truncated IGES file, on which OpenCASCADE's reader crashes, is refused as cut short", "[meshing][cad][hostile]") {
  const fs::path whole = scratch("whole.igs"), cut = scratch("cut.igs");
  testing::writeIges(testing::edgeOf(testing::testSpline()), whole);
  std::ifstream in(whole, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // Cut inside the B-spline's parameter records (the second of them), as an interrupted copy would.
  const std::size_t second = text.find("P0000002");
  REQUIRE(second != std::string::npos);
  std::ofstream(cut, std::ios::binary) << text.substr(0, second - 30);
  CHECK_THAT(meshErrorOf(cut, [&] { meshing::rodsFromCad(cut, {}); }), Catch::Contains("without IGES's Terminate record") &&
                                                                         Catch::Contains("cut short"));
  CHECK(meshing::rodsFromCad(whole, {}).structure.rods.size() == 1);
}
