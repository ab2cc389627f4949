"""Learning and using policies: Brax PPO training, policy files and ONNX export, the paper's
evaluation, the CPU runner on the closed chain (with the foot IMUs' estimates), playback and
rendering, and JAX setup (compilation cache, compatibility)."""
