"""The foundation of every layer: errors, settings declarations, atomic writes, interrupts,
frames, the compiled-kernel loader."""
