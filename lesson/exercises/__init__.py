"""The lesson's exercises, one file each: a stub to fill in; `python lesson/grade.py exN` grades it."""
