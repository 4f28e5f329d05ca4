from setuptools import Extension, find_packages, setup

# The element kernels are plain C (no Python API), built here and loaded with ctypes.
kernels = Extension("hyperelastic._kernels", sources=["hyperelastic/_kernels.c"],
                    extra_compile_args=["-O3", "-march=native", "-fno-math-errno", "-std=c99"])

setup(name="hyperelastic", version="0.1.0",
      description="Implicit FEM for stiff hyperelastic solids on PETSc/SNES",
      packages=find_packages(include=["hyperelastic", "hyperelastic.*"]),
      ext_modules=[kernels],
      entry_points={"console_scripts": ["hyperelastic=hyperelastic.cli:main"]},
      python_requires=">=3.9")
