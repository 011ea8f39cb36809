!> The Terrace version.
module terrace_version
    implicit none
    private
    character(len=*), parameter, public :: terrace_version_string = '0.1.0'
end module terrace_version
