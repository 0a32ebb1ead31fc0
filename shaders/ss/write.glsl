// Register-buffered voxel writes (Sec. 3.2 "Voxel updates"): set bits are
// collected in a few words held in registers and written with one atomicOr
// per word when a slot is needed again or at the end, instead of one atomic
// per voxel.  Needs common/bits.glsl and common/voxel_space.glsl.

layout(std430, binding = 3) buffer Grid { uint grid[]; };

const int WRITE_SLOTS = 4;
uint slot_word[WRITE_SLOTS];
uint slot_bits[WRITE_SLOTS];
int slot_next = 0;

void writes_begin() {
    for (int s = 0; s < WRITE_SLOTS; ++s) slot_bits[s] = 0u;
    slot_next = 0;
}

void flush_slot(int s) {
    if (slot_bits[s] != 0u) atomicOr(grid[slot_word[s]], slot_bits[s]);
    slot_bits[s] = 0u;
}

void set_voxel(ivec3 v) {
    uint w = word_index(v);
    uint b = bit_of(uint(v.x));
    for (int s = 0; s < WRITE_SLOTS; ++s) {
        if (slot_bits[s] != 0u && slot_word[s] == w) { slot_bits[s] |= b; return; }
    }
    for (int s = 0; s < WRITE_SLOTS; ++s) {
        if (slot_bits[s] == 0u) { slot_word[s] = w; slot_bits[s] = b; return; }
    }
    flush_slot(slot_next);
    slot_word[slot_next] = w;
    slot_bits[slot_next] = b;
    slot_next = (slot_next + 1) % WRITE_SLOTS;
}

void writes_end() {
    for (int s = 0; s < WRITE_SLOTS; ++s) flush_slot(s);
}
