#include "printer_profiles/gcvf_writer.hpp"

#include "common/markup.hpp"

#include <cmath>
#include <cstring>
#include <sstream>

namespace rodfab::printer_profiles {

namespace {

void putPixel(std::uint8_t* out, const std::array<unsigned char, 4>& rgba) { std::memcpy(out, rgba.data(), 4); }

}  // namespace

std::string gcvfRgbaText(const std::array<unsigned char, 4>& rgba) {
  return std::to_string(rgba[0]) + " " + std::to_string(rgba[1]) + " " + std::to_string(rgba[2]) + " " + std::to_string(rgba[3]);
}

Bytes encodeGcvfLayer(const Bitmap& rigid, const Bitmap& rubbery, const Profile& profile) {
  const auto& background = profile.gcvf.backgroundRgba;
  const auto& rigidRgba = profile.material(MaterialRole::Rigid).rgba;
  const auto& rubberyRgba = profile.material(MaterialRole::Rubbery).rgba;
  const int width = rigid.width();
  return encodePngRgba(width, rigid.height(), profile.xDpi, profile.yDpi, [&](int r, std::uint8_t* out) {
    const std::uint8_t* a = rigid.row(r);
    const std::uint8_t* b = rubbery.row(r);
    for (int byte = 0; byte < static_cast<int>(rigid.stride()); ++byte) {
      const int first = byte * 8, last = std::min(width, first + 8);
      if (!(a[byte] | b[byte])) {  // most bytes of a layer are empty
        for (int x = first; x < last; ++x) putPixel(out + 4 * x, background);
        continue;
      }
      for (int x = first; x < last; ++x) {
        const unsigned bit = 0x80u >> (x - first);
        putPixel(out + 4 * x, (a[byte] & bit) ? rigidRgba : (b[byte] & bit) ? rubberyRgba : background);
      }
    }
  });
}

namespace {

// Text for an XML comment: escaped, and no "--" in it nor a '-' at its end, which XML forbids there
// (a printer named "J750 -- lab" made every job fail its own check: "Double hyphen within comment").
std::string commentText(const std::string& text) {
  std::string out;
  for (const char c : common::escapeMarkup(text)) {
    if (c == '-' && !out.empty() && out.back() == '-') out += ' ';
    out += c;
  }
  if (!out.empty() && out.back() == '-') out += ' ';
  return out;
}

}  // namespace

std::string gcvfConfigXml(const Profile& p, int width, int height, int layers, const std::vector<GcvfMaterialCount>& counts) {
  std::ostringstream x;
  x << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
    << "<!-- GCVF - GrabCAD Voxel Print File, written by rodfab for " << commentText(p.printer) << " -->\n"
    << "<GCVF>\n"
    << "    <Version>" << p.gcvf.version << "</Version>\n"
    << "    <Resolution>\n"
    << "        <XDpi>" << p.xDpi << "</XDpi>\n"
    << "        <YDpi>" << p.yDpi << "</YDpi>\n"
    << "        <SliceThicknessNanoMeter>" << std::llround(p.layerThicknessMm() * 1e6) << "</SliceThicknessNanoMeter>\n"
    << "    </Resolution>\n"
    << "    <SliceDimensions>\n"
    << "        <SliceWidth>" << width << "</SliceWidth>\n"
    << "        <SliceHeight>" << height << "</SliceHeight>\n"
    << "    </SliceDimensions>\n"
    << "    <SliceRange>\n"
    << "        <StartIndex>0</StartIndex>\n"
    << "        <NumberOfSlices>" << layers << "</NumberOfSlices>\n"
    << "    </SliceRange>\n"
    << "    <BitDepth>" << p.gcvf.bitDepth << "</BitDepth>\n"
    << "    <MaxNumberOfColors>" << p.gcvf.maxNumberOfColors << "</MaxNumberOfColors>\n"
    << "    <DataSemantics>Materials</DataSemantics>\n"
    << "    <CreationMode>" << common::escapeMarkup(p.gcvf.creationMode) << "</CreationMode>\n"
    << "    <ImageFilePrefix>" << common::escapeMarkup(p.gcvf.imageFilePrefix) << "</ImageFilePrefix>\n"
    << "    <MaterialList>\n"
    << "        <BackGroundMaterialRGBA>" << gcvfRgbaText(p.gcvf.backgroundRgba) << "</BackGroundMaterialRGBA>\n";
  for (const GcvfMaterialCount& c : counts)
    x << "        <Material>\n"
      << "            <Name>" << common::escapeMarkup(c.material->name) << "</Name>\n"
      << "            <RGBA>" << gcvfRgbaText(c.material->rgba) << "</RGBA>\n"
      << "            <VoxelCount>" << c.voxels << "</VoxelCount>\n"
      << "        </Material>\n";
  x << "    </MaterialList>\n"
    << "</GCVF>\n";
  return x.str();
}

}  // namespace rodfab::printer_profiles
