"""Just enough of ``launch_ros`` for this project's launch files (see ``launch``)."""
