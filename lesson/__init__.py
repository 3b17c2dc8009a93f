"""The class: exercises (lesson/exercises/), their grader (grade.py) and the notebook (lesson.py); docs/lesson.md."""
