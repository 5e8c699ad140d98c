"""bbzide.vm room (see ARCHITECTURE.md)."""
