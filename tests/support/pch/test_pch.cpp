// The translation unit that owns the test executables' precompiled header
// (tests/CMakeLists.txt, BLOT_TEST_PCH): CMake compiles the header with this
// target's flags, and every test executable reuses it. It defines nothing.
