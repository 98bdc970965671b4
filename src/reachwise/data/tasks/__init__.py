"""Built-in task files (YAML), loaded by name with ``reachwise.io.task_file.load_task``."""
