! J2 (von Mises) plasticity with linear isotropic hardening as an Abaqus
! UMAT in free-form Fortran, with state variables, a consistent tangent and
! SAVE data (a call counter) of the kind that makes a UMAT not reentrant:
! the test suite checks it against the closed form of monotonic simple
! shear. PROPS: Young's modulus, Poisson's ratio, initial yield stress,
! hardening modulus H (d sigma_y / d eps_p). STATEV(1) = equivalent
! plastic strain, STATEV(2:7) = plastic strain (11, 22, 33, 12, 13, 23,
! engineering shears). Radial return (Simo & Hughes 1998, box 3.2).
! With NSTATV >= 12 it also records what the host passed, so a test can see
! every argument arrived in its place: STATEV(8) = CELENT, (9) = KINC,
! (10) = NOEL, (11) = DTIME, (12) = DROT(2,1). With NPROPS >= 5 and
! PROPS(5) > 0, an increment whose plastic multiplier exceeds PROPS(5) is
! refused with PNEWDT = 0.5 (asking for a smaller step).
subroutine umat(stress, statev, ddsdde, sse, spd, scd, rpl, ddsddt, drplde, drpldt, &
                stran, dstran, time, dtime, temp, dtemp, predef, dpred, cmname, ndi, nshr, &
                ntens, nstatv, props, nprops, coords, drot, pnewdt, celent, dfgrd0, dfgrd1, &
                noel, npt, layer, kspt, kstep, kinc)
  implicit none
  character(len=80) :: cmname
  integer :: ndi, nshr, ntens, nstatv, nprops, noel, npt, layer, kspt, kstep, kinc
  double precision :: stress(ntens), statev(nstatv), ddsdde(ntens, ntens), sse, spd, scd, &
                      rpl, ddsddt(ntens), drplde(ntens), drpldt, stran(ntens), dstran(ntens), &
                      time(2), dtime, temp, dtemp, predef(1), dpred(1), props(nprops), &
                      coords(3), drot(3, 3), pnewdt, celent, dfgrd0(3, 3), dfgrd1(3, 3)
  double precision :: e, anu, sy0, h, g, alam, bulk, p, q, eqp, dgam, sy, factor
  double precision :: s(6), n(6), nhat(6), theta, thetab
  integer :: i, j
  integer, save :: calls = 0

  calls = calls + 1
  if (ntens /= 6 .or. nstatv < 7) then
    pnewdt = 0.d0
    return
  end if
  e = props(1); anu = props(2); sy0 = props(3); h = props(4)
  if (nstatv >= 12) then
    statev(8) = celent
    statev(9) = dble(kinc)
    statev(10) = dble(noel)
    statev(11) = dtime
    statev(12) = drot(2, 1)
  end if
  g = e / (2.d0 * (1.d0 + anu))
  alam = e * anu / ((1.d0 + anu) * (1.d0 - 2.d0 * anu))
  bulk = alam + 2.d0 * g / 3.d0

  ddsdde = 0.d0
  do i = 1, 3
    do j = 1, 3
      ddsdde(i, j) = alam
    end do
    ddsdde(i, i) = alam + 2.d0 * g
    ddsdde(i + 3, i + 3) = g
  end do
  ! Elastic trial.
  do i = 1, 6
    do j = 1, 6
      stress(i) = stress(i) + ddsdde(i, j) * dstran(j)
    end do
  end do
  p = (stress(1) + stress(2) + stress(3)) / 3.d0
  s(1:3) = stress(1:3) - p
  s(4:6) = stress(4:6)
  q = sqrt(1.5d0 * (s(1)**2 + s(2)**2 + s(3)**2 + 2.d0 * (s(4)**2 + s(5)**2 + s(6)**2)))
  eqp = statev(1)
  sy = sy0 + h * eqp
  if (q <= sy) return
  ! Radial return: dgam = (q - sy) / (3 G + H), exact for linear hardening.
  dgam = (q - sy) / (3.d0 * g + h)
  if (nprops >= 5) then
    if (props(5) > 0.d0 .and. dgam > props(5)) then
      pnewdt = 0.5d0
      return
    end if
  end if
  n = 1.5d0 * s / q
  factor = 1.d0 - 3.d0 * g * dgam / q
  stress(1:3) = p + factor * s(1:3)
  stress(4:6) = factor * s(4:6)
  statev(1) = eqp + dgam
  statev(2:4) = statev(2:4) + dgam * n(1:3)
  statev(5:7) = statev(5:7) + 2.d0 * dgam * n(4:6)
  ! Consistent tangent (Simo & Hughes 1998, box 3.2 and eq. 3.3.13):
  ! C = K 1x1 + 2 G theta I_dev - 2 G thetab nhat x nhat, nhat = s / |s|,
  ! theta = 1 - 3 G dgam / q_trial, thetab = 1 / (1 + H / (3 G)) - (1 - theta).
  ! Engineering shear strains: the shear columns take the tensor components
  ! of nhat, the shear diagonal G theta.
  theta = factor
  thetab = 1.d0 / (1.d0 + h / (3.d0 * g)) - (1.d0 - theta)
  nhat = s / (sqrt(2.d0 / 3.d0) * q)
  ddsdde = 0.d0
  do i = 1, 3
    do j = 1, 3
      ddsdde(i, j) = bulk - 2.d0 * g * theta / 3.d0
    end do
    ddsdde(i, i) = bulk + 4.d0 * g * theta / 3.d0
    ddsdde(i + 3, i + 3) = g * theta
  end do
  do i = 1, 6
    do j = 1, 6
      ddsdde(i, j) = ddsdde(i, j) - 2.d0 * g * thetab * nhat(i) * nhat(j)
    end do
  end do
end subroutine umat
