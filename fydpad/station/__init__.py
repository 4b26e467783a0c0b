"""The multi-rate master station: vision, sensors, rendering and tele-operation loops."""
