!> Sums of autocorrelations by FFT (Wiener-Khinchin), with FFTW's real-to-complex transforms.
!>
!> For series x_s(t), t = 0..n-1 (s: atom and component), with weights w_s, the object returns
!>
!>     c(tau) = sum_s w_s sum_{t=0}^{n-1-tau} x_s(t) x_s(t+tau),     tau = 0..n-1,
!>
!> exactly (to round-off): every series is padded with zeros to L >= 2n (a power of two), so the
!> circular correlation of the padded series has no wrap-around; the power spectra w_s |X_s(k)|^2 are
!> summed (over series and, by the caller, over MPI ranks) and one inverse transform gives c.
!> Cost O(L log L) per series instead of O(n * lags). The velocity autocorrelation (vacf_vdos) and
!> the mean-squared displacement (msd_diffusion) use it.
!>
!> FFTW plans are made with FFTW_ESTIMATE on the object's own arrays when the object is set up;
!> nothing of FFTW is touched unless an analysis that needs it creates one of these objects.
module terrace_fft_correlation
    use, intrinsic :: iso_c_binding
    use terrace_kinds, only: dp
    use terrace_mpi_env, only: sum_all
    implicit none
    private
    include 'fftw3.f03'

    type, public :: autocorrelation_t
        integer :: n = 0                               !< series length
        integer :: length = 0                          !< padded transform length L
        type(c_ptr) :: forward = c_null_ptr, backward = c_null_ptr
        real(c_double), allocatable :: work(:)         !< (0:L-1)
        complex(c_double_complex), allocatable :: spectrum(:)   !< (0:L/2)
        real(dp), allocatable :: power(:)              !< accumulated weighted |X(k)|^2, (0:L/2)
    contains
        procedure :: setup => ac_setup
        procedure :: add => ac_add
        procedure :: reduce => ac_reduce
        procedure :: correlation => ac_correlation
        procedure :: destroy => ac_destroy
    end type autocorrelation_t

    public :: next_power_of_two, cosine_spectrum

contains

    pure integer function next_power_of_two(n) result(p)
        integer, intent(in) :: n
        p = 1
        do while (p < n)
            p = 2*p
        end do
    end function next_power_of_two

    subroutine ac_setup(self, n)
        class(autocorrelation_t), intent(inout) :: self
        integer, intent(in) :: n
        call self%destroy()
        self%n = n
        self%length = next_power_of_two(2*n)
        allocate (self%work(0:self%length - 1), self%spectrum(0:self%length/2), self%power(0:self%length/2))
        self%forward = fftw_plan_dft_r2c_1d(self%length, self%work, self%spectrum, FFTW_ESTIMATE)
        self%backward = fftw_plan_dft_c2r_1d(self%length, self%spectrum, self%work, FFTW_ESTIMATE)
        self%power = 0
    end subroutine ac_setup

    !> Add w * (autocorrelation of x(1:n)) to the sum.
    subroutine ac_add(self, x, w)
        class(autocorrelation_t), intent(inout) :: self
        real(dp), intent(in) :: x(:)
        real(dp), intent(in) :: w
        integer :: k
        self%work(0:self%n - 1) = x(1:self%n)
        self%work(self%n:) = 0
        call fftw_execute_dft_r2c(self%forward, self%work, self%spectrum)
        do k = 0, self%length/2
            self%power(k) = self%power(k) + w*(real(self%spectrum(k), dp)**2 + aimag(self%spectrum(k))**2)
        end do
    end subroutine ac_add

    !> Sum the accumulated spectra over the ranks (collective).
    subroutine ac_reduce(self)
        class(autocorrelation_t), intent(inout) :: self
        call sum_all(self%power)
    end subroutine ac_reduce

    !> c(0:maxlag) from the accumulated spectrum (call reduce first when the series are spread over ranks).
    subroutine ac_correlation(self, maxlag, c)
        class(autocorrelation_t), intent(inout) :: self
        integer, intent(in) :: maxlag
        real(dp), intent(out) :: c(0:maxlag)
        self%spectrum = cmplx(self%power, 0.0_dp, kind=c_double_complex)
        call fftw_execute_dft_c2r(self%backward, self%spectrum, self%work)
        c = self%work(0:maxlag)/real(self%length, dp)
    end subroutine ac_correlation

    subroutine ac_destroy(self)
        class(autocorrelation_t), intent(inout) :: self
        if (c_associated(self%forward)) call fftw_destroy_plan(self%forward)
        if (c_associated(self%backward)) call fftw_destroy_plan(self%backward)
        self%forward = c_null_ptr; self%backward = c_null_ptr
        if (allocated(self%work)) deallocate (self%work, self%spectrum, self%power)
    end subroutine ac_destroy

    !> Cosine transform of an even sequence given by its half f(0:m), zero-padded to `length`
    !> (a power of two > 2m): s(k) = f(0) + 2 sum_{j=1}^{m} f(j) cos(2 pi j k / length), k = 0..length/2.
    subroutine cosine_spectrum(f, m, length, s)
        integer, intent(in) :: m, length
        real(dp), intent(in) :: f(0:m)
        real(dp), intent(out) :: s(0:length/2)
        real(c_double), allocatable :: buf(:)
        complex(c_double_complex), allocatable :: out(:)
        type(c_ptr) :: plan
        integer :: j
        allocate (buf(0:length - 1), out(0:length/2))
        plan = fftw_plan_dft_r2c_1d(length, buf, out, FFTW_ESTIMATE)
        buf = 0
        buf(0:m) = f
        do j = 1, m
            buf(length - j) = f(j)
        end do
        call fftw_execute_dft_r2c(plan, buf, out)
        s = real(out, dp)
        call fftw_destroy_plan(plan)
    end subroutine cosine_spectrum

end module terrace_fft_correlation
