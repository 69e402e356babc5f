# Blot::Bullet: the Bullet libraries cloth/ links, as one imported target.
# CMake's FindBullet (the module mode Debian's libbullet-dev answers) defines
# only variables; a target lets the exported Blot::cloth name its Bullet
# dependency instead of baking absolute library paths into the package.
# Included after find_package(Bullet) by the top-level CMakeLists.txt and by
# the installed BlotConfig.cmake.
if(NOT TARGET Blot::Bullet)
  add_library(Blot::Bullet INTERFACE IMPORTED)
  # Dependents first: BulletSoftBody needs BulletDynamics, Collision, LinearMath.
  set(_blot_bullet_libs ${BULLET_SOFTBODY_LIBRARY} ${BULLET_DYNAMICS_LIBRARY}
                        ${BULLET_COLLISION_LIBRARY} ${BULLET_MATH_LIBRARY})
  if(NOT _blot_bullet_libs)
    set(_blot_bullet_libs ${BULLET_LIBRARIES})
  endif()
  set(_blot_bullet_include ${BULLET_INCLUDE_DIRS})
  if(BULLET_ROOT_DIR)
    # Bullet's own BulletConfig.cmake (a Bullet built from source) gives paths
    # relative to BULLET_ROOT_DIR and bare library names.
    set(_blot_bullet_include ${BULLET_ROOT_DIR}/${BULLET_INCLUDE_DIR})
    set_target_properties(Blot::Bullet PROPERTIES
      INTERFACE_LINK_DIRECTORIES "${BULLET_ROOT_DIR}/${BULLET_LIBRARY_DIRS}")
  endif()
  set_target_properties(Blot::Bullet PROPERTIES
    INTERFACE_INCLUDE_DIRECTORIES "${_blot_bullet_include}"
    INTERFACE_LINK_LIBRARIES "${_blot_bullet_libs}")
  if(BULLET_DEFINITIONS)
    set_target_properties(Blot::Bullet PROPERTIES INTERFACE_COMPILE_DEFINITIONS "${BULLET_DEFINITIONS}")
  endif()
  unset(_blot_bullet_libs)
  unset(_blot_bullet_include)
endif()
