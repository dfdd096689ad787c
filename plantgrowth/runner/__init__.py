"""Running a scene: the time loop, the output directory (who may write, what is written, crash
safety, resume) and ``run_scene``, which checks a scene on the domain it runs on before anything
is written.

May import: ``plantgrowth.models`` and everything below it.
"""
