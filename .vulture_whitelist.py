"""Names vulture (`make lint`) reports as unused in lubrig_ros that are used, and why.

Vulture reads the package alone, so a name used only by the tests is reported: that is how it
finds test-only helpers. Every name listed here is used by something vulture cannot see; a name
that fits no section below is dead code and goes, not here.
"""

# ruff: noqa
_ = object()

# Read or called by name: ROS message and descriptor fields set on rclpy objects,
# foxglove-websocket's server listener callbacks, PyYAML's dumper and argparse settings, the
# console-script entry point of setup.py, RigParameters properties read through the kernel's
# RIG_LAYOUT, FieldSpec flags read by rig_fields(**flags).
_.growth_rate, _.sticking, _.longest_stick, _.dim, _.frame_id, _.height
_.simulated_displacement, _.measured_rejected
_.floating_point_range, _.integer_range, _.additional_constraints
_.on_client_advertise, _.on_client_unadvertise, _.on_message_data, _.on_get_parameters
_.on_parameters_subscribe, _.on_parameters_unsubscribe, _.on_set_parameters, request_id
_.default_flow_style, _._negative_number_matcher
belt_drive
_.damping, _.on_rig

# Registered when their module is imported (the friction-law and band-profile registries).
LAW, SinusoidalBand

# Dataclass fields read through dataclasses.fields / asdict: a law's parameters become its kernel's
# array in field order; result records are written out whole (JSON, YAML, diagnostics).
shear_modulus, reference_activation_time, reference_velocity, reference_viscosity
stribeck_velocity, stribeck_exponent, regularization_velocity
time_min, time_max, zone_name, resonance_detail, iterations, global_significance, period_s
resyncs, _.resyncs, warm_up_seconds

# Layouts named in full: the slots of the compiled stepper's arrays and the MCAP opcodes.
RIG_SIZE, H, W, X, OP_ATTACHMENT

# Facts with their home in the package that the tests check the running system against (the
# shadow topics of the contract, the shipped viewer layouts, the figures' colour maps) and
# counters a session or writer keeps for its observers.
SHADOW_TOPICS, SHIPPED, UNIFORM_CMAPS
_.bad_updates, _.chunks_flushed, _.samples_seen

# The library's API for scientific Python users, documented in docs/ (model.md, wavelets.md,
# report.md, recording.md, extending.md): functions a script calls that no command happens to call.
stability_map, dominant_frequencies, recording_summary, unregister_profile
_.reconstructed_variance, _.advance_states, _.substeps
