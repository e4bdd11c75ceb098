# revolve_target_defaults(target): warnings (errors when REVOLVE_WERROR) and sanitizers.
function(revolve_target_defaults target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow=local -Wnon-virtual-dtor)
  if(REVOLVE_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
  if(REVOLVE_SANITIZE)
    target_compile_options(${target} PRIVATE -fsanitize=address,undefined -fno-omit-frame-pointer
                                             -fno-sanitize-recover=undefined)
    target_link_options(${target} PRIVATE -fsanitize=address,undefined)
  endif()
endfunction()
