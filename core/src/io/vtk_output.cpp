#include <talus/io/vtk_output.hpp>

#include "xml_text.hpp"

#include <talus/io/output_file.hpp>
#include <talus/sdk/voigt.hpp>

#include <fmt/format.h>

#include <cstdint>
#include <limits>
#include <string_view>

namespace talus {

namespace fs = std::filesystem;

namespace {

// One appended data array: its XML header and its bytes.
struct VtkArray {
    std::string name, type;
    int components = 1;
    std::vector<char> bytes;
    template <class T>
    void put(T v) {
        const char *p = reinterpret_cast<const char *>(&v);
        bytes.insert(bytes.end(), p, p + sizeof(T));
    }
};

// A field-data string array in VTK's ASCII form: each string as its byte
// values, each ended by a 0 (what vtkXMLWriter writes for vtkStringArray).
std::string string_array(std::string_view name, const std::vector<std::string> &values) {
    std::string body;
    for (const std::string &v : values) {
        for (unsigned char c : v)
            body += fmt::format("{} ", static_cast<int>(c));
        body += "0 ";
    }
    return fmt::format("        <Array type=\"String\" Name=\"{}\" NumberOfTuples=\"{}\" "
                       "format=\"ascii\">\n          {}\n        </Array>\n",
                       name, values.size(), body);
}

// The point data arrays of a particle file, in order: the 13 fixed ones,
// then the state variables by name across materials (as wide as the widest
// material's).
std::vector<VtkArray> point_arrays(const Scenario &sc,
                                   const std::vector<std::string> &state_fields) {
    std::vector<VtkArray> a = {{"id", "Int64", 1, {}},         {"group", "Int32", 1, {}},
                               {"material", "Int32", 1, {}},   {"displacement", "Float64", 3, {}},
                               {"velocity", "Float64", 3, {}}, {"stress", "Float64", 9, {}},
                               {"p", "Float64", 1, {}},        {"q", "Float64", 1, {}},
                               {"volume", "Float64", 1, {}},   {"J", "Float64", 1, {}},
                               {"density", "Float64", 1, {}},  {"mass", "Float64", 1, {}},
                               {"F", "Float64", 9, {}}};
    for (const std::string &name : state_fields) {
        std::uint32_t size = 0;
        for (const auto &m : sc.materials)
            for (const auto &v : m.spec.state.vars)
                if (v.name == name) size = std::max(size, v.size);
        a.push_back({name, "Float64", static_cast<int>(size), {}});
    }
    return a;
}

} // namespace

void write_vtu(const fs::path &file, const Simulation &sim,
               const std::vector<std::string> &state_fields) {
    const Scenario &sc = sim.scenario();
    const int D = sc.dim;
    std::size_t n = 0; // this rank's
    for (const ParticleSet &s : sim.sets())
        n += s.n;
    std::vector<VtkArray> point_data = point_arrays(sc, state_fields);
    for (VtkArray &a : point_data)
        a.bytes.reserve(n * static_cast<std::size_t>(a.components) * 8);
    // References into point_data, which does not grow from here on.
    VtkArray &id = point_data[0], &grp = point_data[1], &mat = point_data[2], &disp = point_data[3],
             &vel = point_data[4], &sig = point_data[5], &pp = point_data[6], &qq = point_data[7],
             &vol = point_data[8], &jj = point_data[9], &rho = point_data[10],
             &mass = point_data[11], &F = point_data[12];
    // The state fields, after the 13 fixed arrays.
    struct StateField {
        std::string name;
        std::uint32_t size = 1;
        std::size_t array = 0;
    };
    std::vector<StateField> sf;
    for (std::size_t k = 13; k < point_data.size(); ++k)
        sf.push_back(StateField{point_data[k].name,
                                static_cast<std::uint32_t>(point_data[k].components), k});
    VtkArray points{"Points", "Float64", 3, {}};
    for (const ParticleSet &s : sim.sets()) {
        // Where each written state field sits in this material's state
        // vector (nullptr: the material has no such variable).
        std::vector<const StateInfo *> info(sf.size(), nullptr);
        for (std::size_t f = 0; f < sf.size(); ++f)
            for (const auto &v : sc.materials[s.material].spec.state.vars)
                if (v.name == sf[f].name) info[f] = &v;
        for (std::size_t p = 0; p < s.n; ++p) {
            id.put<std::int64_t>(s.id[p]);
            grp.put<std::int32_t>(s.group[p]);
            mat.put<std::int32_t>(static_cast<std::int32_t>(s.material));
            for (int d = 0; d < 3; ++d) {
                const std::size_t dd = static_cast<std::size_t>(d);
                const bool in = d < D;
                points.put<double>(in ? s.x[dd][p] : 0.0);
                disp.put<double>(in ? s.x[dd][p] - s.x0[dd][p] : 0.0);
                vel.put<double>(in ? s.v[dd][p] : 0.0);
            }
            const sdk::Vec6 v6 = Eigen::Map<const sdk::Vec6>(&s.stress[6 * p]);
            const sdk::Mat3 m = sdk::stress_to_matrix(v6);
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b)
                    sig.put<double>(m(a, b));
            pp.put<double>(sdk::mean_pressure(v6));
            qq.put<double>(sdk::von_mises(v6));
            vol.put<double>(s.J[p] * s.vol0[p]);
            jj.put<double>(s.J[p]);
            rho.put<double>(s.mass[p] / (s.J[p] * s.vol0[p]));
            mass.put<double>(s.mass[p]);
            double Fp[9];
            s.F_of(p, Fp);
            for (double f : Fp) // row-major, as VTK reads a 3x3 tensor
                F.put<double>(f);
            for (std::size_t f = 0; f < sf.size(); ++f) {
                const StateInfo *in = info[f];
                for (std::uint32_t k = 0; k < sf[f].size; ++k)
                    point_data[sf[f].array].put<double>(
                        in && k < in->size ? s.state[s.state_size * p + in->offset + k]
                                           : std::numeric_limits<double>::quiet_NaN());
            }
        }
    }
    // One vertex cell per particle.
    VtkArray conn{"connectivity", "Int64", 1, {}}, offs{"offsets", "Int64", 1, {}},
        types{"types", "UInt8", 1, {}};
    for (std::size_t i = 0; i < n; ++i) {
        conn.put<std::int64_t>(static_cast<std::int64_t>(i));
        offs.put<std::int64_t>(static_cast<std::int64_t>(i + 1));
        types.put<std::uint8_t>(1); // VTK_VERTEX
    }

    std::vector<std::string> group_names, material_names;
    for (const GroupSpec &g : sc.groups)
        group_names.push_back(g.name);
    for (const NamedMaterial &m : sc.materials)
        material_names.push_back(m.name);

    std::string xml;
    std::uint64_t offset = 0;
    auto header = [&](const VtkArray &a, bool named) {
        xml += fmt::format(
            "        <DataArray type=\"{}\"{} NumberOfComponents=\"{}\" format=\"appended\" "
            "offset=\"{}\"/>\n",
            a.type, named ? fmt::format(" Name=\"{}\"", xml_escape(a.name)) : std::string(),
            a.components, offset);
        offset += sizeof(std::uint64_t) + a.bytes.size();
    };
    xml += "<?xml version=\"1.0\"?>\n"
           "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
           "header_type=\"UInt64\">\n"
           "  <UnstructuredGrid>\n"
           "      <FieldData>\n";
    xml += string_array("group_names", group_names);
    xml += string_array("material_names", material_names);
    xml += fmt::format("        <DataArray type=\"Float64\" Name=\"TimeValue\" "
                       "NumberOfTuples=\"1\" format=\"ascii\">{:.17g}</DataArray>\n",
                       sim.time());
    // Which stage the file belongs to (docs/scenario-reference.md, stages).
    xml += fmt::format("        <DataArray type=\"Int32\" Name=\"Stage\" NumberOfTuples=\"1\" "
                       "format=\"ascii\">{}</DataArray>\n",
                       sim.stage());
    if (const std::string &stage = sim.stages()[sim.stage()].name; !stage.empty())
        xml += string_array("stage_name", {stage});
    xml += "      </FieldData>\n";
    xml += fmt::format("    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n", n, n);
    xml += "      <PointData>\n";
    for (const VtkArray &a : point_data)
        header(a, true);
    xml += "      </PointData>\n      <Points>\n";
    header(points, false);
    xml += "      </Points>\n      <Cells>\n";
    header(conn, true);
    header(offs, true);
    header(types, true);
    xml += "      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n  <AppendedData "
           "encoding=\"raw\">\n   _";

    AtomicFile out(file);
    out.write(xml);
    auto blob = [&](const VtkArray &a) {
        const std::uint64_t len = a.bytes.size();
        out.write(std::string_view(reinterpret_cast<const char *>(&len), sizeof len));
        out.write(std::string_view(a.bytes.data(), a.bytes.size()));
    };
    for (const VtkArray &a : point_data)
        blob(a);
    blob(points);
    blob(conn);
    blob(offs);
    blob(types);
    out.write("\n  </AppendedData>\n</VTKFile>\n");
    out.commit();
}

void write_pvtu(const fs::path &file, const Simulation &sim,
                const std::vector<std::string> &state_fields,
                const std::vector<std::string> &pieces) {
    std::string x = "<?xml version=\"1.0\"?>\n<VTKFile type=\"PUnstructuredGrid\" "
                    "version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n"
                    "  <PUnstructuredGrid GhostLevel=\"0\">\n    <PPointData>\n";
    for (const VtkArray &a : point_arrays(sim.scenario(), state_fields))
        x += fmt::format("      <PDataArray type=\"{}\" Name=\"{}\" NumberOfComponents=\"{}\"/>\n",
                         a.type, xml_escape(a.name), a.components);
    x += "    </PPointData>\n    <PPoints>\n"
         "      <PDataArray type=\"Float64\" NumberOfComponents=\"3\"/>\n    </PPoints>\n";
    for (const std::string &p : pieces)
        x += fmt::format("    <Piece Source=\"{}\"/>\n", xml_escape(p));
    x += "  </PUnstructuredGrid>\n</VTKFile>\n";
    write_file_atomically(file, x);
}

} // namespace talus
