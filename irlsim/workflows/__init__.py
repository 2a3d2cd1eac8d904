"""The workflows of the command line as library functions, each with a typed request; ``pipelines/``
only parses arguments into these and calls them, and ``irlsim demo`` and DAgger chain them.

| module | function | request | command |
|---|---|---|---|
| :mod:`~irlsim.workflows.net` | ``build_network`` | ``force`` | ``irlsim net`` |
| :mod:`~irlsim.workflows.collect` | ``collect_dataset`` | ``CollectRun`` | ``irlsim collect`` |
| :mod:`~irlsim.workflows.train` | ``train_models`` | ``TrainRun`` | ``irlsim train`` |
| :mod:`~irlsim.workflows.evaluate` | ``evaluate_runs`` | ``EvaluateRun`` | ``irlsim evaluate`` |
| :mod:`~irlsim.workflows.drive` | ``drive_models`` | ``DriveRun`` | ``irlsim drive`` |
| :mod:`~irlsim.workflows.dagger` | ``run_dagger`` | ``DaggerRun`` (``DaggerConfig``) | ``irlsim dagger`` |
| :mod:`~irlsim.workflows.scenarios` | ``check_scenario_run`` | ``CheckRun`` | ``irlsim scenario check`` |
| :mod:`~irlsim.workflows.scenarios` | ``generate_networks`` | ``GenerateRun`` |``irlsim scenario generate``|
| :mod:`~irlsim.workflows.sweep` | ``sweep_networks`` | ``SweepRun`` | ``irlsim scenario sweep`` |

:mod:`~irlsim.workflows.steps`: ``exit_status``, a step's exit status as ``irlsim`` gives it (chains).
Nothing is imported here: collection never loads torch, training does.
"""
