"""The problem files shipped with qpik (installed as ``qpik.problem_files``; see ``qpik.problems``)."""
