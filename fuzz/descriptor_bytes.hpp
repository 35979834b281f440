// The byte form of a plugin's library descriptor that the descriptor
// fuzzer decodes (fuzz/plugin_descriptor.cpp) and the seed tool writes from
// the shipped plugins (fuzz/descriptor_seeds.cpp).
//
// Read front to back; past the end every value reads as zero.
//   struct size: u8, 0 = the host's sizeof, else that many bytes (a 1.0
//                descriptor, a truncated one, or one from a newer SDK)
//   string:      u8 length, 255 = a null pointer, then the bytes
//   library:     size u32 abi_major u32 abi_minor str name str version
//                u8 bits (1: get_extension set, 2: models null) u8 n_models
//   model:       u8 null, size, u32 flags, str id name version doc,
//                u8 functions (bits: create destroy update create_ex
//                instance_state init_state, 64: params null, 128: state
//                null), u8 n_params, u8 n_state, then the params, the state
//   param:       u8 null, size, u32 type flags, str key unit doc,
//                f64 default min max typical, u32 min_count max_count,
//                str default_string typical_string
//   state:       u8 null, size, u32 flags size, str name unit doc,
//                f64 initial_value
//
// Each structure is allocated with exactly the size it claims (at least its
// struct_size field), so a host read past what a plugin declared is a heap
// overflow AddressSanitizer reports.
#pragma once

#include <talus/material_abi.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <deque>
#include <memory>
#include <string>
#include <vector>

namespace talus::fuzz {

class ByteReader {
  public:
    ByteReader(const std::uint8_t *data, std::size_t size) : data_(data), size_(size) {}
    std::uint8_t u8() { return pos_ < size_ ? data_[pos_++] : 0; }
    std::uint32_t u32() {
        std::uint32_t v = 0;
        for (int i = 0; i < 4; ++i)
            v |= std::uint32_t(u8()) << (8 * i);
        return v;
    }
    double f64() {
        std::uint64_t bits = 0;
        for (int i = 0; i < 8; ++i)
            bits |= std::uint64_t(u8()) << (8 * i);
        double v;
        std::memcpy(&v, &bits, sizeof v);
        return v;
    }
    // nullptr for a null string; the text is kept in `store`.
    const char *str(std::deque<std::string> &store) {
        const std::uint8_t n = u8();
        if (n == 255) return nullptr;
        std::string s;
        for (std::uint8_t i = 0; i < n; ++i)
            s.push_back(static_cast<char>(u8()));
        store.push_back(std::move(s));
        return store.back().c_str();
    }

  private:
    const std::uint8_t *data_;
    std::size_t size_, pos_ = 0;
};

class ByteWriter {
  public:
    void u8(std::uint8_t v) { bytes.push_back(v); }
    void u32(std::uint32_t v) {
        for (int i = 0; i < 4; ++i)
            u8(static_cast<std::uint8_t>(v >> (8 * i)));
    }
    void f64(double v) {
        std::uint64_t bits;
        std::memcpy(&bits, &v, sizeof v);
        for (int i = 0; i < 8; ++i)
            u8(static_cast<std::uint8_t>(bits >> (8 * i)));
    }
    void str(const char *s) {
        if (!s) return u8(255);
        const std::size_t n = std::min<std::size_t>(std::strlen(s), 254);
        u8(static_cast<std::uint8_t>(n));
        for (std::size_t i = 0; i < n; ++i)
            u8(static_cast<std::uint8_t>(s[i]));
    }
    template <class T>
    void size(std::uint32_t struct_size) {
        u8(struct_size == sizeof(T) || struct_size > 254 ? 0
                                                         : static_cast<std::uint8_t>(struct_size));
    }
    std::vector<std::uint8_t> bytes;
};

// Stand-ins for the plugin's functions: the checks look at whether they are
// set, never call them.
inline std::int32_t dummy_create(const double *, std::uint32_t, talus_instance **, talus_error *) {
    return TALUS_STATUS_FAILED;
}
inline void dummy_destroy(talus_instance *) {}
inline std::int32_t dummy_update(const talus_instance *, const talus_batch *, talus_error *) {
    return TALUS_STATUS_FAILED;
}
inline const void *dummy_extension(const char *) { return nullptr; }

// A descriptor decoded from bytes, owning every structure and string.
class DecodedLibrary {
  public:
    explicit DecodedLibrary(ByteReader &in) {
        talus_library lib{};
        const std::uint32_t size = struct_size<talus_library>(in);
        lib.struct_size = size;
        lib.abi_major = in.u32();
        lib.abi_minor = in.u32();
        lib.name = in.str(strings_);
        lib.version = in.str(strings_);
        const std::uint8_t bits = in.u8();
        if (bits & 1) lib.get_extension = &dummy_extension;
        lib.n_models = in.u8() % 17;
        std::vector<const talus_model *> &models = model_tables_.emplace_back();
        for (std::uint32_t m = 0; m < lib.n_models; ++m)
            models.push_back(model(in));
        lib.models = (bits & 2) ? nullptr : models.data();
        library_ = place(lib, size);
    }
    const talus_library *library() const { return library_; }

  private:
    template <class T>
    static std::uint32_t struct_size(ByteReader &in) {
        const std::uint8_t code = in.u8();
        return code == 0 ? static_cast<std::uint32_t>(sizeof(T)) : code;
    }
    // A copy of `full` in a block of exactly `size` bytes (at least the
    // struct_size field): what a plugin of that struct_size hands over.
    template <class T>
    const T *place(const T &full, std::uint32_t size) {
        const std::size_t bytes = std::max<std::size_t>(size, sizeof(std::uint32_t));
        blocks_.push_back(std::make_unique<unsigned char[]>(bytes));
        std::memcpy(blocks_.back().get(), &full, std::min(bytes, sizeof(T)));
        return reinterpret_cast<const T *>(blocks_.back().get());
    }
    const talus_model *model(ByteReader &in) {
        if (in.u8() & 1) return nullptr;
        talus_model md{};
        const std::uint32_t size = struct_size<talus_model>(in);
        md.struct_size = size;
        md.flags = in.u32();
        md.id = in.str(strings_);
        md.name = in.str(strings_);
        md.version = in.str(strings_);
        md.doc = in.str(strings_);
        const std::uint8_t fn = in.u8();
        if (fn & 1) md.create = &dummy_create;
        if (fn & 2) md.destroy = &dummy_destroy;
        if (fn & 4) md.update = &dummy_update;
        if (fn & 8)
            md.create_ex = [](const talus_create_args *, talus_instance **,
                              talus_error *) -> std::int32_t { return TALUS_STATUS_FAILED; };
        if (fn & 16)
            md.instance_state = [](const talus_instance *, talus_state_layout *,
                                   talus_error *) -> std::int32_t { return TALUS_STATUS_FAILED; };
        if (fn & 32)
            md.init_state = [](const talus_instance *, const talus_batch *,
                               talus_error *) -> std::int32_t { return TALUS_STATUS_FAILED; };
        md.n_params = in.u8() % 65;
        md.n_state = in.u8() % 65;
        std::vector<const talus_param_desc *> &params = param_tables_.emplace_back();
        for (std::uint32_t i = 0; i < md.n_params; ++i)
            params.push_back(param(in));
        std::vector<const talus_state_desc *> &state = state_tables_.emplace_back();
        for (std::uint32_t i = 0; i < md.n_state; ++i)
            state.push_back(state_var(in));
        md.params = (fn & 64) ? nullptr : params.data();
        md.state = (fn & 128) ? nullptr : state.data();
        return place(md, size);
    }
    const talus_param_desc *param(ByteReader &in) {
        if (in.u8() & 1) return nullptr;
        talus_param_desc d{};
        const std::uint32_t size = struct_size<talus_param_desc>(in);
        d.struct_size = size;
        d.type = in.u32();
        d.flags = in.u32();
        d.key = in.str(strings_);
        d.unit = in.str(strings_);
        d.doc = in.str(strings_);
        d.default_value = in.f64();
        d.min_value = in.f64();
        d.max_value = in.f64();
        d.typical_value = in.f64();
        d.min_count = in.u32();
        d.max_count = in.u32();
        d.default_string = in.str(strings_);
        d.typical_string = in.str(strings_);
        return place(d, size);
    }
    const talus_state_desc *state_var(ByteReader &in) {
        if (in.u8() & 1) return nullptr;
        talus_state_desc d{};
        const std::uint32_t size = struct_size<talus_state_desc>(in);
        d.struct_size = size;
        d.flags = in.u32();
        d.size = in.u32();
        d.name = in.str(strings_);
        d.unit = in.str(strings_);
        d.doc = in.str(strings_);
        d.initial_value = in.f64();
        return place(d, size);
    }

    std::deque<std::string> strings_;
    std::vector<std::unique_ptr<unsigned char[]>> blocks_;
    // Deques: a table's address stays put while later ones are added.
    std::deque<std::vector<const talus_model *>> model_tables_;
    std::deque<std::vector<const talus_param_desc *>> param_tables_;
    std::deque<std::vector<const talus_state_desc *>> state_tables_;
    const talus_library *library_ = nullptr;
};

} // namespace talus::fuzz
