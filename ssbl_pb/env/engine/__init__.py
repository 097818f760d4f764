"""The engine: one step of N copies (kernels), their state (batched), the env's parameters."""
