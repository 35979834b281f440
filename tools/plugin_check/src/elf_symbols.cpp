#include <talus/error.hpp>
#include <talus/plugin_check/elf_symbols.hpp>

#include <fmt/format.h>

#include <elf.h>

#include <cstring>
#include <fstream>
#include <iterator>

namespace talus {

std::vector<std::string> exported_symbols(const std::filesystem::path &file) {
    std::ifstream in(file, std::ios::binary);
    if (!in) throw Error(fmt::format("{}: cannot open", file.string()));
    const std::vector<char> bytes((std::istreambuf_iterator<char>(in)),
                                  std::istreambuf_iterator<char>());
    auto fail = [&](const char *why) -> Error {
        return Error(fmt::format("{}: cannot read the ELF symbol table: {}", file.string(), why));
    };
    // Every read is bounds-checked: the file is untrusted input.
    auto view = [&](std::size_t off, std::size_t len) -> const char * {
        if (off > bytes.size() || len > bytes.size() - off) throw fail("truncated file");
        return bytes.data() + off;
    };
    if (bytes.size() < SELFMAG || std::memcmp(bytes.data(), ELFMAG, SELFMAG) != 0)
        throw fail("not an ELF file");
    Elf64_Ehdr eh;
    std::memcpy(&eh, view(0, sizeof(eh)), sizeof(eh));
    if (eh.e_ident[EI_CLASS] != ELFCLASS64) throw fail("not a 64-bit ELF file");
    if (eh.e_shentsize != sizeof(Elf64_Shdr)) throw fail("unexpected section header size");

    std::vector<Elf64_Shdr> sections(eh.e_shnum);
    for (std::size_t i = 0; i < sections.size(); ++i)
        std::memcpy(&sections[i], view(eh.e_shoff + i * sizeof(Elf64_Shdr), sizeof(Elf64_Shdr)),
                    sizeof(Elf64_Shdr));

    std::vector<std::string> out;
    for (const Elf64_Shdr &sh : sections) {
        if (sh.sh_type != SHT_DYNSYM) continue;
        if (sh.sh_link >= sections.size() || sh.sh_entsize != sizeof(Elf64_Sym))
            throw fail("bad .dynsym");
        const Elf64_Shdr &strtab = sections[sh.sh_link];
        const char *names = view(strtab.sh_offset, strtab.sh_size);
        for (std::size_t k = 0; k < sh.sh_size / sizeof(Elf64_Sym); ++k) {
            Elf64_Sym s;
            std::memcpy(&s, view(sh.sh_offset + k * sizeof(Elf64_Sym), sizeof(Elf64_Sym)),
                        sizeof(s));
            const unsigned bind = ELF64_ST_BIND(s.st_info);
            const unsigned vis = ELF64_ST_VISIBILITY(s.st_other);
            if (s.st_shndx == SHN_UNDEF || s.st_name == 0) continue;
            if (bind != STB_GLOBAL && bind != STB_WEAK && bind != STB_GNU_UNIQUE) continue;
            if (vis != STV_DEFAULT && vis != STV_PROTECTED) continue;
            if (s.st_name >= strtab.sh_size) throw fail("symbol name outside the string table");
            out.emplace_back(names + s.st_name,
                             strnlen(names + s.st_name, strtab.sh_size - s.st_name));
        }
    }
    return out;
}

} // namespace talus
