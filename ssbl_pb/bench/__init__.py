"""Benchmarks and harnesses whose figures land in docs/ (one module per table): the simulator's speed (simulator),
camera representations (camera), training throughput (training), tracking (tracking_speed, sim_tracking), facing
(facing), deploy against the virtual Pepper (deploy, perception_errors) and the sweep pool (sweep_pool). Not product
code: nothing below imports it."""
