// IGES models written as text, for the rods-from-cad tests: what OpenCASCADE's writer never writes
// (a composite curve pointing at a directory entry the file does not hold, a B-spline weight of 0).
#pragma once

#include <cstdio>
#include <string>
#include <vector>

namespace rodfab::cad_test {

// One entity: its type number and its parameters as the record writes them (after the type).
struct IgesEntity {
  int type;
  std::string parameters;  // "0.,0.,0.,20.,0.,0." for a line
};

// An IGES file in millimetres whose entities, in order, are the directory entries D1, D3, D5, ...
// (two directory lines each), each with its parameters on records of 64 characters.
inline std::string igesModel(const std::vector<IgesEntity>& entities) {
  auto line = [](const std::string& data, char section, int sequence) {
    char tail[16];
    std::snprintf(tail, sizeof tail, "%c%7d", section, sequence);
    return data + std::string(72 - data.size(), ' ') + tail + "\n";
  };
  auto field = [](int value) {
    const std::string text = std::to_string(value);
    return std::string(8 - text.size(), ' ') + text;
  };
  const std::string global = "1H,,1H;,4Htest,6Ht.iges,4Htest,4Htest,32,38,6,308,15,4Htest,1.0,2,2HMM,1,0.1,15H20261206.120000,"
                             "1.0D-6,10000.,4Hme  ,4Horg ,11,0,15H20261206.120000;";
  std::string text = line("rods-from-cad test", 'S', 1), directory, parameters;
  int globalLines = 0, parameterLines = 0;
  for (std::size_t at = 0; at < global.size(); at += 72) text += line(global.substr(at, 72), 'G', ++globalLines);
  for (std::size_t i = 0; i < entities.size(); ++i) {
    const int entry = static_cast<int>(2 * i + 1), first = parameterLines + 1;
    const std::string record = std::to_string(entities[i].type) + "," + entities[i].parameters + ";";
    for (std::size_t at = 0; at < record.size(); at += 64) {
      const std::string chunk = record.substr(at, 64);
      parameters += line(chunk + std::string(64 - chunk.size(), ' ') + field(entry), 'P', ++parameterLines);
    }
    const std::string type = field(entities[i].type), zero = field(0), blank(8, ' ');
    directory += line(type + field(first) + zero + zero + zero + zero + zero + zero + "00000000", 'D', entry);
    directory += line(type + zero + zero + field(parameterLines - first + 1) + zero + blank + blank + blank + zero, 'D', entry + 1);
  }
  // std::string("S") + ..., not "S" + ...: GCC 12's -Wrestrict misfires on a literal plus a string temporary.
  const std::string terminate = std::string("S") + field(1).substr(1) + "G" + field(globalLines).substr(1) + "D" +
                                field(static_cast<int>(2 * entities.size())).substr(1) + "P" + field(parameterLines).substr(1);
  return text + directory + parameters + line(terminate, 'T', 1);
}

}  // namespace rodfab::cad_test
