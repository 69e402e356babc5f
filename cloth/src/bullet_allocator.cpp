// The recycling allocator for Bullet's raw allocations (ClothDef::recycleBulletAllocations)
// and what installs it.
#include "bullet_cloth_impl.h"

#include <LinearMath/btAlignedAllocator.h>
#include <malloc.h>

#include <array>
#include <cstdlib>
#include <mutex>

namespace blot::cloth::detail {

namespace {

// Bullet 3.24's btSoftBody::solveConstraints calls applyClusters twice per
// substep, and each call allocates and frees two node-sized scratch arrays
// even when the body has no clusters (4 mallocs per substep, measured). A
// game-loop step must not allocate, so Bullet's raw allocations go through a
// small recycling cache: a freed block is kept (up to kSlots of them) and
// handed out again for a request it fits without wasting more than half of
// it. Every block still comes from malloc and goes back to free, so blocks
// Bullet allocated before the cache was installed are handled too
// (malloc_usable_size tells their size). Installed once per process, on the
// first BulletCloth; process-wide, since Bullet's allocator is.
// Rejected: patching Bullet or giving the body cluster scratch of its own
// (applyClusters is not virtual).
class RecyclingBulletAllocator {
 public:
  static void install() {
    static std::once_flag once;
    std::call_once(once, [] { btAlignedAllocSetCustom(&allocate, &release); });
  }

 private:
  static constexpr int kSlots = 16;
  struct Slot {
    void* block = nullptr;
    size_t size = 0;
  };
  static std::mutex& lock() {
    static std::mutex m;
    return m;
  }
  static std::array<Slot, kSlots>& slots() {
    static std::array<Slot, kSlots> s;
    return s;
  }
  static void* allocate(size_t size) {
    {
      std::lock_guard<std::mutex> guard(lock());
      for (Slot& slot : slots()) {
        if (slot.block != nullptr && slot.size >= size && slot.size <= 2 * size) {
          void* block = slot.block;
          slot.block = nullptr;
          return block;
        }
      }
    }
    return std::malloc(size);
  }
  static void release(void* block) {
    if (block == nullptr) return;
    {
      std::lock_guard<std::mutex> guard(lock());
      for (Slot& slot : slots()) {
        if (slot.block == nullptr) {
          slot.block = block;
          slot.size = malloc_usable_size(block);
          return;
        }
      }
    }
    std::free(block);
  }
};

}  // namespace

void installRecyclingBulletAllocator() { RecyclingBulletAllocator::install(); }

}  // namespace blot::cloth::detail
