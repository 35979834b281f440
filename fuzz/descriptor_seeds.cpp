// Writes the seed corpus of the descriptor fuzzer: the descriptors of the
// given plugin files, loaded as talus does, in the byte form of
// descriptor_bytes.hpp. Usage: talus_fuzz_descriptor_seeds OUT_DIR PLUGIN...
#include "descriptor_bytes.hpp"

#include <talus/material/plugin_loader.hpp>

#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>

namespace {

void write_model(talus::fuzz::ByteWriter &w, const talus_model &md) {
    w.u8(0);
    w.size<talus_model>(md.struct_size);
    w.u32(md.flags);
    w.str(md.id);
    w.str(md.name);
    w.str(md.version);
    w.str(md.doc);
    const bool v11 = TALUS_HAS_FIELD(talus_model, &md, init_state);
    std::uint8_t fn = 0;
    if (md.create) fn |= 1;
    if (md.destroy) fn |= 2;
    if (md.update) fn |= 4;
    if (v11 && md.create_ex) fn |= 8;
    if (v11 && md.instance_state) fn |= 16;
    if (v11 && md.init_state) fn |= 32;
    w.u8(fn);
    w.u8(static_cast<std::uint8_t>(md.n_params));
    w.u8(static_cast<std::uint8_t>(md.n_state));
    for (std::uint32_t i = 0; i < md.n_params; ++i) {
        const talus_param_desc &d = *md.params[i];
        w.u8(0);
        w.size<talus_param_desc>(d.struct_size);
        w.u32(d.type);
        w.u32(d.flags);
        w.str(d.key);
        w.str(d.unit);
        w.str(d.doc);
        w.f64(d.default_value);
        w.f64(d.min_value);
        w.f64(d.max_value);
        w.f64(d.typical_value);
        const bool typed = TALUS_HAS_FIELD(talus_param_desc, &d, typical_string);
        w.u32(typed ? d.min_count : 0);
        w.u32(typed ? d.max_count : 0);
        w.str(typed ? d.default_string : nullptr);
        w.str(typed ? d.typical_string : nullptr);
    }
    for (std::uint32_t i = 0; i < md.n_state; ++i) {
        const talus_state_desc &d = *md.state[i];
        w.u8(0);
        w.size<talus_state_desc>(d.struct_size);
        w.u32(d.flags);
        w.u32(d.size);
        w.str(d.name);
        w.str(d.unit);
        w.str(d.doc);
        w.f64(d.initial_value);
    }
}

} // namespace

int main(int argc, char **argv) {
    if (argc < 3) {
        std::fprintf(stderr, "usage: %s OUT_DIR PLUGIN...\n", argv[0]);
        return 2;
    }
    try {
        const std::filesystem::path out = argv[1];
        std::filesystem::create_directories(out);
        for (int a = 2; a < argc; ++a) {
            const auto lib = talus::PluginLibrary::open(argv[a]);
            talus::fuzz::ByteWriter w;
            w.u8(0); // the host's library struct size
            w.u32(lib->abi_major());
            w.u32(lib->abi_minor());
            w.str(lib->name().c_str());
            w.str(lib->version().c_str());
            w.u8(lib->extension("talus.none") != nullptr ? 1 : 0);
            w.u8(static_cast<std::uint8_t>(lib->models().size()));
            for (const talus::Model &m : lib->models())
                write_model(w, m.raw());
            const auto file = out / (lib->name() + ".bin");
            std::ofstream f(file, std::ios::binary);
            f.write(reinterpret_cast<const char *>(w.bytes.data()),
                    static_cast<std::streamsize>(w.bytes.size()));
            if (!f.flush()) {
                std::fprintf(stderr, "%s: cannot write\n", file.c_str());
                return 1;
            }
        }
    } catch (const std::exception &e) {
        std::fprintf(stderr, "talus_fuzz_descriptor_seeds: %s\n", e.what());
        return 1;
    }
    return 0;
}
