"""The scenarios that ship with irlsim: one folder each with a ``scenario.toml`` (see irlsim.road.scenario),
and ``vtypes.add.xml``, irlsim's vehicle types for every scenario. Data only."""
