#include "printer_profiles/inspect_gcvf.hpp"

#include "printer_profiles/gcvf_writer.hpp"

#include <libxml/parser.h>
#include <libxml/tree.h>

#include <cmath>
#include <cstring>
#include <map>
#include <memory>
#include <optional>

namespace rodfab::printer_profiles {

GcvfLayerImage decodeGcvfLayer(std::span<const std::uint8_t> png, const Profile& profile,
                               const std::vector<const ProfileMaterial*>& materials, int width, int height) {
  GcvfLayerImage out;
  const auto& background = profile.gcvf.backgroundRgba;
  bool sizeOk = true;
  const auto begin = [&](const RgbaHeader& h) {
    sizeOk = h.width == width && h.height == height;
    if (!sizeOk) return;
    for (std::size_t n = 0; n < materials.size(); ++n) out.bitmaps.emplace_back(width, height);
  };
  const auto row = [&](int r, const std::uint8_t* pixels) {
    if (!sizeOk) return;
    for (int x = 0; x < width; ++x) {
      const std::uint8_t* p = pixels + 4 * x;
      if (std::memcmp(p, background.data(), 4) == 0) continue;
      bool known = false;
      for (std::size_t n = 0; n < materials.size() && !known; ++n)
        if (std::memcmp(p, materials[n]->rgba.data(), 4) == 0) {
          out.bitmaps[n].set(x, r);
          known = true;
        }
      if (known) continue;
      if (out.foreignPixels++ == 0) {
        std::memcpy(out.firstForeign.data(), p, 4);
        out.firstForeignColumn = x;
        out.firstForeignRow = r;
      }
    }
  };
  const RgbaHeader h = decodePngRgba(png, static_cast<std::uint64_t>(width) * static_cast<std::uint64_t>(height), begin, row);
  if (!sizeOk)
    throw ImageError(std::to_string(h.width) + " x " + std::to_string(h.height) + " pixels; the job's images are " +
                     std::to_string(width) + " x " + std::to_string(height));
  out.xPixelsPerMetre = h.xPixelsPerMetre;
  out.yPixelsPerMetre = h.yPixelsPerMetre;
  return out;
}

namespace {

using XmlDoc = std::unique_ptr<xmlDoc, decltype(&xmlFreeDoc)>;

std::string name(const xmlNode* n) { return reinterpret_cast<const char*>(n->name); }

// The text of an element with text only (no child elements), trimmed of surrounding white space.
std::optional<std::string> textOf(const xmlNode* element) {
  std::string text;
  for (const xmlNode* c = element->children; c; c = c->next) {
    if (c->type == XML_ELEMENT_NODE) return std::nullopt;
    if (c->type == XML_TEXT_NODE || c->type == XML_CDATA_SECTION_NODE) text += reinterpret_cast<const char*>(c->content);
  }
  const std::size_t a = text.find_first_not_of(" \t\r\n"), b = text.find_last_not_of(" \t\r\n");
  return a == std::string::npos ? std::string() : text.substr(a, b - a + 1);
}

std::string shown(const std::string& s) {
  std::string out;
  for (const char c : s.substr(0, 60))
    out += (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) ? '?' : c;
  return "\"" + out + (s.size() > 60 ? "...\"" : "\"");
}

class ConfigChecker {
public:
  std::vector<std::string> problems;

  // The one child element `key` of `parent` (path names it in messages); nullptr after a problem.
  const xmlNode* only(const xmlNode* parent, const std::string& path, const std::string& key) {
    const xmlNode* found = nullptr;
    int count = 0;
    for (const xmlNode* c = parent->children; c; c = c->next)
      if (c->type == XML_ELEMENT_NODE && name(c) == key) found = count++ ? found : c;
    if (count == 1) return found;
    problems.push_back(path + "/" + key + ": " + (count ? "appears " + std::to_string(count) + " times; expected once" : "missing"));
    return nullptr;
  }
  // Child `key` must hold exactly `want`.
  void expect(const xmlNode* parent, const std::string& path, const std::string& key, const std::string& want) {
    const xmlNode* e = only(parent, path, key);
    if (!e) return;
    const std::optional<std::string> text = textOf(e);
    if (!text) problems.push_back(path + "/" + key + ": expected text " + shown(want) + ", found elements");
    else if (*text != want) problems.push_back(path + "/" + key + ": expected " + shown(want) + ", found " + shown(*text));
  }
  void expect(const xmlNode* parent, const std::string& path, const std::string& key, long long want) {
    expect(parent, path, key, std::to_string(want));
  }
};

void checkMaterialList(ConfigChecker& c, const xmlNode* list, const Profile& p, const std::vector<MaterialTotals>& counted,
                       bool countsKnown) {
  const std::string path = "GCVF/MaterialList";
  c.expect(list, path, "BackGroundMaterialRGBA", gcvfRgbaText(p.gcvf.backgroundRgba));
  std::vector<const xmlNode*> entries;
  for (const xmlNode* n = list->children; n; n = n->next)
    if (n->type == XML_ELEMENT_NODE && name(n) == "Material") entries.push_back(n);
    else if (n->type == XML_ELEMENT_NODE && name(n) != "BackGroundMaterialRGBA")
      c.problems.push_back(path + "/" + name(n) + ": unexpected element");
  if (entries.size() != counted.size()) {
    c.problems.push_back(path + ": lists " + std::to_string(entries.size()) + " materials; the job's images hold " +
                         std::to_string(counted.size()) + " (the profile's model materials)");
    return;
  }
  for (std::size_t n = 0; n < entries.size(); ++n) {
    const std::string at = path + "/Material[" + std::to_string(n + 1) + "]";
    const ProfileMaterial& want = p.material(counted[n].role);
    c.expect(entries[n], at, "Name", want.name);
    c.expect(entries[n], at, "RGBA", gcvfRgbaText(want.rgba));
    if (countsKnown) {
      c.expect(entries[n], at, "VoxelCount", std::to_string(counted[n].voxels));
    } else if (const xmlNode* e = c.only(entries[n], at, "VoxelCount")) {
      const std::optional<std::string> t = textOf(e);
      if (!t || t->empty() || t->size() > 19 || t->find_first_not_of("0123456789") != std::string::npos)
        c.problems.push_back(at + "/VoxelCount: expected a whole number, found " + (t ? shown(*t) : std::string("elements")));
    }
  }
}

}  // namespace

std::vector<std::string> checkGcvfConfig(std::span<const std::uint8_t> xml, const Profile& p, int width, int height, int layers,
                                         const std::vector<MaterialTotals>& counted, bool countsKnown) {
  ConfigChecker c;
  // No network, no DTD loading, entities left unexpanded: a hostile file can only be malformed.
  const int options = XML_PARSE_NONET | XML_PARSE_NOERROR | XML_PARSE_NOWARNING;
  XmlDoc doc(xmlReadMemory(reinterpret_cast<const char*>(xml.data()), static_cast<int>(xml.size()), "ConfigFile.xml", nullptr, options),
             xmlFreeDoc);
  if (!doc) {
    const xmlError* e = xmlGetLastError();
    c.problems.push_back(std::string("not well-formed XML") +
                         (e && e->message ? " (line " + std::to_string(e->line) + ": " + shown(e->message) + ")" : ""));
    xmlResetLastError();
    return c.problems;
  }
  const xmlNode* root = xmlDocGetRootElement(doc.get());
  if (!root || name(root) != "GCVF") {
    c.problems.push_back("the root element is " + (root ? shown(name(root)) : std::string("missing")) + "; expected GCVF");
    return c.problems;
  }
  c.expect(root, "GCVF", "Version", p.gcvf.version);
  if (const xmlNode* r = c.only(root, "GCVF", "Resolution")) {
    c.expect(r, "GCVF/Resolution", "XDpi", p.xDpi);
    c.expect(r, "GCVF/Resolution", "YDpi", p.yDpi);
    c.expect(r, "GCVF/Resolution", "SliceThicknessNanoMeter", std::llround(p.layerThicknessMm() * 1e6));
  }
  if (const xmlNode* d = c.only(root, "GCVF", "SliceDimensions")) {
    c.expect(d, "GCVF/SliceDimensions", "SliceWidth", width);
    c.expect(d, "GCVF/SliceDimensions", "SliceHeight", height);
  }
  if (const xmlNode* s = c.only(root, "GCVF", "SliceRange")) {
    c.expect(s, "GCVF/SliceRange", "StartIndex", 0);
    c.expect(s, "GCVF/SliceRange", "NumberOfSlices", layers);
  }
  c.expect(root, "GCVF", "BitDepth", p.gcvf.bitDepth);
  c.expect(root, "GCVF", "MaxNumberOfColors", p.gcvf.maxNumberOfColors);
  c.expect(root, "GCVF", "DataSemantics", "Materials");
  c.expect(root, "GCVF", "CreationMode", p.gcvf.creationMode);
  c.expect(root, "GCVF", "ImageFilePrefix", p.gcvf.imageFilePrefix);
  if (const xmlNode* list = c.only(root, "GCVF", "MaterialList")) checkMaterialList(c, list, p, counted, countsKnown);
  return c.problems;
}

}  // namespace rodfab::printer_profiles
